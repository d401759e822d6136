#!/usr/bin/env bash
# make test's test stages, side by side. In the foreground, the Kilted build's DDS and end-to-end suites (tests/ros,
# tests/e2e); in the background the lint and type checks, and the Jazzy environment's install (a no-op when it is
# installed) then the Jazzy build's DDS and end-to-end suites, their output kept in build/checks.log and
# build/test-jazzy.log and printed at the end. The Kilted core tests (tests/core: no DDS, every one busy on the CPU)
# run where a chain ends first: after the Kilted DDS stage, or after the Jazzy stage (their output then in
# build/test-core.log). A DDS test waits part of its time (discovery, a paced simulator, a process starting), so the
# last of them leave a 2-core machine partly idle: the core tests fill that, whichever chain runs out of work first.
# usage: JAZZY_INSTALL="..." CHECKS="..." KILTED_PYTEST="..." JAZZY_PYTEST="..." tools/test_suites.sh   (the Makefile
# sets them; KILTED_PYTEST without test paths)
# Exit code: 0 when the checks and every stage passed. Ctrl-C (or SIGTERM) stops them all; each stops its own
# simulators.
# Safety net: a stage whose run fails runs its failed tests once more, and says so first; only a second failure
# fails the stage. Every DDS timing failure seen had its cause looked for and fixed (issue 16 closed after five whole
# runs beside two busy processes passed without the rerun), but a loaded 2-core machine can still meet one not seen
# yet, and the printed note keeps it visible. TB4_TEST_RERUN=0 turns the rerun off (the suite must pass as it is).
set -uo pipefail
cd "$(dirname "$0")/.."
: "${JAZZY_INSTALL:?set by the Makefile}" "${CHECKS:?set by the Makefile}"
: "${KILTED_PYTEST:?set by the Makefile}" "${JAZZY_PYTEST:?set by the Makefile}"
mkdir -p build
jazzy_log=build/test-jazzy.log
checks_log=build/checks.log
core_log=build/test-core.log
core_claim=build/test-core.claimed  # made (atomically) by the chain that runs the core tests
core_rc_file=build/test-core.rc
rm -rf "$core_claim" "$core_rc_file" "$core_log"
rerun_note="[make test] some tests failed: running only those once more (DDS timing under load; see issue 16)"
stage() {  # stage PYTEST-COMMAND: the run, and the failed tests once more if it failed
  $1 && return 0
  [ "${TB4_TEST_RERUN:-1}" = 0 ] && return 1
  echo "$rerun_note"
  $1 --last-failed
}
# The Kilted core tests, by the first chain to call this (else nothing); their own pytest cache, for the rerun.
core_if_first() {
  mkdir "$core_claim" 2>/dev/null || return 0
  echo "[make test] Kilted build: the core tests"
  stage "$KILTED_PYTEST -o cache_dir=.pytest_cache_core tests/core"
  echo $? > "$core_rc_file"
}

set -m  # each background job gets a process group of its own, and SIGINT is not ignored in it
$CHECKS >"$checks_log" 2>&1 &
checks_pid=$!
{
  $JAZZY_INSTALL && stage "$JAZZY_PYTEST"
  jazzy_rc=$?
  core_if_first >"$core_log" 2>&1
  exit "$jazzy_rc"
} >"$jazzy_log" 2>&1 &
jazzy_pid=$!
set +m
stop_background() {
  local pid
  for pid in "$checks_pid" "$jazzy_pid"; do kill -INT -- "-$pid" 2>/dev/null || true; done
  for _ in $(seq 1 100); do
    kill -0 "$checks_pid" 2>/dev/null || kill -0 "$jazzy_pid" 2>/dev/null || return 0
    sleep 0.1
  done
  for pid in "$checks_pid" "$jazzy_pid"; do kill -TERM -- "-$pid" 2>/dev/null || true; done
}
trap 'stop_background; exit 130' INT TERM

echo "[make test] beside: the lint and type checks ($checks_log), the Jazzy environment's install and the Jazzy"
echo "[make test] build's DDS and e2e suites ($jazzy_log); the Kilted core tests after whichever ends first"
echo "[make test] Kilted build: the DDS and e2e suites"
stage "$KILTED_PYTEST tests/ros tests/e2e"
kilted_rc=$?
echo "[make test] Kilted DDS and e2e stage exit code $kilted_rc"
core_if_first
echo "[make test] waiting for the checks and the Jazzy stage"
wait "$checks_pid"
checks_rc=$?
wait "$jazzy_pid"
jazzy_rc=$?
trap - INT TERM
echo "[make test] lint and type checks: their output"
cat "$checks_log"
echo "[make test] Jazzy build (nav2_msgs as Nav2 Jazzy speaks it): its output"
cat "$jazzy_log"
if [ -s "$core_log" ]; then
  echo "[make test] Kilted build: the core tests (run after the Jazzy stage): their output"
  cat "$core_log"
fi
core_rc=$(cat "$core_rc_file" 2>/dev/null || echo "none (not run)")
echo "[make test] exit codes: checks $checks_rc, Kilted DDS and e2e $kilted_rc, Kilted core $core_rc, Jazzy stage $jazzy_rc"
[ "$checks_rc" -eq 0 ] && [ "$kilted_rc" -eq 0 ] && [ "$core_rc" = 0 ] && [ "$jazzy_rc" -eq 0 ]
