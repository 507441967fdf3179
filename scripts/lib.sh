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
