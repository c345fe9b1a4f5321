#!/bin/sh
# One setup stage, quietly: a line saying what it does, the elapsed seconds while it runs
# (long stages such as the pip install take a minute), its output kept in a log that is
# shown only when it fails.
# Usage: sh .ci/step.sh LOG "label" command [args...]
set -u
LOG=$1; LABEL=$2; shift 2
mkdir -p "$(dirname "$LOG")"
printf '%s\n' "== $LABEL" >>"$LOG"
start=$(date +%s)
"$@" >>"$LOG" 2>&1 &
pid=$!
if [ -t 1 ]; then
  while kill -0 "$pid" 2>/dev/null; do
    printf '\r%s … %ss' "$LABEL" "$(( $(date +%s) - start ))"; sleep 1
  done
else  # a log file or CI: one dot every 5 s, no carriage returns
  printf '%s …' "$LABEL"
  n=0
  while kill -0 "$pid" 2>/dev/null; do
    sleep 1; n=$((n + 1)); [ $((n % 5)) -eq 0 ] && printf '.'
  done
fi
wait "$pid"; rc=$?
elapsed=$(( $(date +%s) - start ))
if [ "$rc" -ne 0 ]; then
  printf ' failed after %ss (exit %s); the last lines of %s:\n' "$elapsed" "$rc" "$LOG"
  tail -n 30 "$LOG"
  exit "$rc"
fi
[ -t 1 ] && printf '\r%s … done (%ss)\n' "$LABEL" "$elapsed" || printf ' done (%ss)\n' "$elapsed"
