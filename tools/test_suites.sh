#!/usr/bin/env bash
# make test's test stages, side by side: the Kilted build's whole suite in the foreground; in the background the
# lint and type checks and the docs build (make docs: mkdocs --strict), and the Jazzy environments' install (a no-op
# when they are installed) then the Jazzy build's DDS and end-to-end suites and the cross-distro stage (Jazzy with
# Kilted's middleware), their output kept in build/checks.log and build/test-jazzy.log and printed once the Kilted
# stage has ended. The Kilted stage is the longest chain, so nothing
# waits in front of it. Each stage spends much of its time waiting on simulated time and discovery, so one stage
# leaves a 2-core machine partly idle; two whole suites side by side, with a busy process beside them, is also the
# stress run that shook out the DDS timing races (issue 16).
# usage: JAZZY_INSTALL="..." CHECKS="..." KILTED_PYTEST="..." JAZZY_PYTEST="..." CROSS_PYTEST="..."
# tools/test_suites.sh   (the Makefile sets them)
# Exit code: 0 when the checks and every stage passed. Ctrl-C (or SIGTERM) stops them all; each stops its own
# simulators.
# Safety net: a stage whose run fails runs its failed tests once more, and says so first; only a second failure
# fails the stage. Every DDS timing failure seen had its cause looked for and fixed (issue 16: whole runs beside busy
# processes pass without the rerun), but a loaded 2-core machine can still meet one not seen yet, and the printed
# note keeps it visible. TB4_TEST_RERUN=0 turns the rerun off (the suite must pass as it is).
set -uo pipefail
cd "$(dirname "$0")/.."
: "${JAZZY_INSTALL:?set by the Makefile}" "${CHECKS:?set by the Makefile}"
: "${KILTED_PYTEST:?set by the Makefile}" "${JAZZY_PYTEST:?set by the Makefile}" "${CROSS_PYTEST:?set by the Makefile}"
mkdir -p build
jazzy_log=build/test-jazzy.log
checks_log=build/checks.log
rerun_note="[make test] some tests failed: running only those once more (DDS timing under load; see issue 16)"
stage() {  # stage PYTEST-COMMAND: the run, and the failed tests once more if it failed
  $1 && return 0
  [ "${TB4_TEST_RERUN:-1}" = 0 ] && return 1
  echo "$rerun_note"
  $1 --last-failed
}
jazzy_chain() {  # the Jazzy stage, then the cross-distro stage (after it even when it failed: both are reported)
  local rc=0
  $JAZZY_INSTALL || return 1
  stage "$JAZZY_PYTEST" || rc=1
  echo "[make test] cross-distro stage: Jazzy's middleware with Kilted's, both over Jazzy's nav2_msgs"
  stage "$CROSS_PYTEST" || rc=1
  return $rc
}

set -m  # each background job gets a process group of its own, and SIGINT is not ignored in it
$CHECKS >"$checks_log" 2>&1 &
checks_pid=$!
jazzy_chain >"$jazzy_log" 2>&1 &
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

echo "[make test] beside: the lint and type checks and the docs build ($checks_log), the Jazzy environments'"
echo "[make test] install, the Jazzy build's DDS and e2e suites and the cross-distro stage ($jazzy_log)"
echo "[make test] Kilted build: the whole suite"
stage "$KILTED_PYTEST"
kilted_rc=$?
echo "[make test] Kilted stage exit code $kilted_rc; waiting for the checks and the Jazzy stage"
wait "$checks_pid"
checks_rc=$?
wait "$jazzy_pid"
jazzy_rc=$?
trap - INT TERM
echo "[make test] lint and type checks, docs build: their output"
cat "$checks_log"
echo "[make test] Jazzy build (ROS 2 Jazzy's middleware, Nav2 Jazzy's nav2_msgs), then the cross-distro stage: output"
cat "$jazzy_log"
echo "[make test] exit codes: checks and docs $checks_rc, Kilted stage $kilted_rc, Jazzy and cross-distro stages $jazzy_rc"
[ "$checks_rc" -eq 0 ] && [ "$kilted_rc" -eq 0 ] && [ "$jazzy_rc" -eq 0 ]
