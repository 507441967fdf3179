# Shell functions the scripts share; `source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"` (bash).

# wait_until_up URL PID SECONDS LOG [any]
#   Polls URL every 0.2 s until it answers 2xx (with `any`: any HTTP status). Returns 0 then.
#   Returns 1, after printing why and the last 30 lines of LOG to stderr, as soon as process PID
#   has exited (its exit status is collected) or after SECONDS seconds.
wait_until_up() {
    local url=$1 pid=$2 limit=$3 log=$4 fail=-f start=$SECONDS
    [[ "${5:-}" == any ]] && fail=
    until curl -s $fail -o /dev/null --max-time 2 "$url"; do
        if ! kill -0 "$pid" 2>/dev/null; then
            wait "$pid" 2>/dev/null || true
            echo "process $pid exited before $url answered (log: $log):" >&2
            tail -n 30 "$log" >&2 || true
            return 1
        fi
        if ((SECONDS - start >= limit)); then
            echo "$url did not answer within $limit s (log: $log):" >&2
            tail -n 30 "$log" >&2 || true
            return 1
        fi
        sleep 0.2
    done
}

# The name that prefixes the messages of the script that sources this file: its file name
# without `.sh`.
SCRIPT_NAME="$(basename "${BASH_SOURCE[1]:-$0}" .sh)"

# log MESSAGE...: a progress line on stderr, prefixed with the script's name.
log() { echo "$SCRIPT_NAME: $*" >&2; }

# die MESSAGE...: an error line on stderr, prefixed with the script's name, then exit 1.
die() {
    echo "$SCRIPT_NAME: error: $*" >&2
    exit 1
}

# need_value OPTION [VALUE...]: dies unless OPTION is followed by a non-empty value. Called as
# `need_value "$@"` from an argument loop.
need_value() { [[ $# -ge 2 && -n "$2" ]] || die "$1 needs a value (see --help)"; }

# stop_process PID: asks process PID to stop (SIGTERM), gives it 10 s, then kills it (SIGKILL,
# said on stderr), and collects its exit status. Nothing happens for a PID that has exited.
stop_process() {
    local pid=$1 i
    if kill -0 "$pid" 2>/dev/null; then
        kill -TERM "$pid" 2>/dev/null || true
        for ((i = 0; i < 100; i++)); do
            kill -0 "$pid" 2>/dev/null || break
            sleep 0.1
        done
        if kill -0 "$pid" 2>/dev/null; then
            log "process $pid did not stop in 10 s after SIGTERM; sending SIGKILL"
            kill -KILL "$pid" 2>/dev/null || true
        fi
    fi
    wait "$pid" 2>/dev/null || true
}

# pinned_venv DIR PACKAGE VERSION: a Python virtualenv at DIR with PACKAGE==VERSION installed by
# pip (nothing global), made again only when the installed version differs.
pinned_venv() {
    local venv=$1 package=$2 version=$3
    if [[ ! -x "$venv/bin/python" ]] || ! "$venv/bin/python" -c \
        "import importlib.metadata as m, sys; sys.exit(m.version('$package') != '$version')" 2>/dev/null; then
        python3 -m venv "$venv"
        "$venv/bin/pip" install --quiet --disable-pip-version-check "$package==$version"
    fi
}
