#!/usr/bin/env bash
# How often the C library's builds of its math functions for two CPUs disagree (a measurement, not
# in CI; README, *Tests*, "The same bits on every machine").
#
# Compiles scripts/libm_builds.c with the system's C compiler, runs it once as is and once with
# glibc told the CPU has no AVX2 and no FMA (GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX2,-FMA), and
# prints, per function, how many of 5,000,000 results differ. On an x86-64 CPU with FMA and
# glibc 2.33 or later the two runs take different builds; elsewhere both take the same one and
# nothing differs.
#
# Usage: scripts/libm_builds.sh [--out DIR]
#   --out DIR   where the program and its two result files go (default target/libm-builds; the
#               result files, 680 MB, are removed at the end)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="$ROOT/target/libm-builds"
while [[ $# -gt 0 ]]; do
    case "$1" in
        --out) need_value "$@"; OUT="$2"; shift 2 ;;
        -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
        *) die "unknown argument '$1' (see --help)" ;;
    esac
done
command -v cc > /dev/null || die "no C compiler (cc) on PATH"
mkdir -p "$OUT"
cc -O2 -fno-builtin -o "$OUT/libm_builds" "$ROOT/scripts/libm_builds.c" -lm
trap 'rm -f "$OUT/default.bin" "$OUT/no-fma.bin"' EXIT
log "results with the C library's builds for this CPU"
"$OUT/libm_builds" write "$OUT/default.bin" || die "writing the results failed"
log "results with its builds for a CPU without AVX2 and FMA"
GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX2,-FMA "$OUT/libm_builds" write "$OUT/no-fma.bin" \
    || die "writing the results failed"
"$OUT/libm_builds" compare "$OUT/default.bin" "$OUT/no-fma.bin"
