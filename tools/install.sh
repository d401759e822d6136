#!/usr/bin/env bash
# Create the project's virtual environment and install everything into it: the ROS 2 wheels, the build tools
# our interface packages need, and the project itself (editable), which builds nav2_msgs, irobot_create_msgs,
# geographic_msgs and tf2_msgs into the venv, with every extra ([all], and [dev], [docs] and [cluster] to test, build
# the docs and sweep on Ray). Safe to re-run.
# TB4_ROS_DISTRO picks the ROS 2 distribution: kilted (default) or jazzy, whose own middleware (rclpy, rmw_fastrtps,
# Fast DDS) and rosidl then build and run everything, as on a TurtleBot 4 running Jazzy (pyproject.toml's
# [tool.tb4.jazzy] lists its wheels).
# With TB4_BASE_VENV (an installed environment, as make install-jazzy-wire passes .venv), the new environment overlays
# it instead (tools/venv_overlay.py): it builds and holds only nav2_msgs in TB4_ROS_DISTRO's wire format and the
# project's editable install, and takes everything else, the middleware too, from the base, which must stay where it
# is (Jazzy's wire format on Kilted's middleware).
set -euo pipefail
PYTHON=${PYTHON:-python3}
VENV=${VENV:-.venv}
# The ROS 2 distribution: kilted (default) or jazzy (TurtleBot 4s running Jazzy); with TB4_BASE_VENV, only the
# nav2_msgs wire format.
TB4_ROS_DISTRO=${TB4_ROS_DISTRO:-kilted}
TB4_BASE_VENV=${TB4_BASE_VENV:-}
cd "$(dirname "$0")/.."

say() { printf '\033[1m[install]\033[0m %s\n' "$*"; }
die() { printf '[install] error: %s\n' "$*" >&2; exit 1; }
# Where the time goes: each step's wall time, printed at the end (with the interface packages' own steps).
TIMES=()
now_ms() { date +%s%3N; }
step_start=$(now_ms)
timed() {  # timed LABEL: close the step that started at the last call (or at the top) under LABEL
  local end ms
  end=$(now_ms)
  ms=$((end - step_start))
  TIMES+=("$(printf '%5d.%d s  %s' $((ms / 1000)) $((ms % 1000 / 100)) "$1")")
  step_start=$end
}

requirements() {  # requirements build|all: from pyproject.toml, one per line, with TB4_ROS_DISTRO's ROS wheels
  "$PY" tools/pyproject_requirements.py "$1" --distro "$TB4_ROS_DISTRO"
}

case "$TB4_ROS_DISTRO" in
  kilted|jazzy) ;;
  *) die "TB4_ROS_DISTRO is '$TB4_ROS_DISTRO': it must be kilted (the default) or jazzy" ;;
esac
command -v "$PYTHON" >/dev/null || die "$PYTHON not found: install Python 3.10+ (Debian: apt-get install python3 python3-venv)"
"$PYTHON" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 10) else 1)' \
  || die "Python 3.10 or newer is needed ($("$PYTHON" --version 2>&1) found)"
if [ -n "$TB4_BASE_VENV" ]; then
  [ -x "$TB4_BASE_VENV/bin/tb4" ] \
    || die "TB4_BASE_VENV is '$TB4_BASE_VENV': no installed environment there (make install first)"
  TB4_BASE_VENV=$(realpath "$TB4_BASE_VENV")
  [ "$TB4_BASE_VENV" != "$(realpath -m "$VENV")" ] || die "an environment cannot overlay itself ($VENV)"
  PYTHON="$TB4_BASE_VENV/bin/python"  # the overlay runs the base's Python, so the base's packages fit it
fi
for tool in cc c++; do
  command -v "$tool" >/dev/null || die "no C/C++ compiler ($tool) found: on Debian run: apt-get install build-essential"
done

# An environment made the other way (a full one where an overlay is asked for, or the reverse) is made anew.
if [ -x "$VENV/bin/python" ]; then
  is_overlay=no; wants_overlay=no
  ls "$VENV"/lib/python3*/site-packages/tb4_venv_overlay.pth >/dev/null 2>&1 && is_overlay=yes
  [ -n "$TB4_BASE_VENV" ] && wants_overlay=yes
  if [ "$is_overlay" != "$wants_overlay" ]; then
    say "$VENV is $([ "$is_overlay" = yes ] && echo 'an overlay' || echo 'a full environment'): making it anew"
    rm -rf "$VENV"
  fi
fi
# A full environment holds one distribution's middleware: one made for the other is made anew, not mixed (pip would
# downgrade some wheels and leave the others). Environments from before this file was written hold Kilted's.
distro_file="$VENV/tb4-ros-distro"
if [ -x "$VENV/bin/python" ] && [ -z "$TB4_BASE_VENV" ]; then
  made_for=$(cat "$distro_file" 2>/dev/null || echo kilted)
  if [ "$made_for" != "$TB4_ROS_DISTRO" ]; then
    say "$VENV holds ROS 2 $made_for's middleware: making it anew for $TB4_ROS_DISTRO"
    rm -rf "$VENV"
  fi
fi
if [ ! -x "$VENV/bin/python" ]; then
  say "creating $VENV"
  if ! "$PYTHON" -m venv "$VENV" 2>/dev/null; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
      say "python3-venv is missing; installing it with apt-get"
      apt-get update -qq && apt-get install -y -qq python3-venv >/dev/null
      "$PYTHON" -m venv "$VENV"
    else
      die "cannot create a virtual environment: on Debian run: sudo apt-get install python3-venv"
    fi
  fi
fi
PY="$VENV/bin/python"
[ -n "$TB4_BASE_VENV" ] || echo "$TB4_ROS_DISTRO" > "$distro_file"
# One build folder per wire format, so a Kilted and a Jazzy environment can live side by side.
build_dir="build/$TB4_ROS_DISTRO"
cmake_defines=(-C "cmake.define.TB4_ROS_DISTRO=$TB4_ROS_DISTRO")
if [ -n "$TB4_BASE_VENV" ]; then
  site_packages=$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
  cp tools/venv_overlay.py "$site_packages/tb4_venv_overlay.py"
  printf 'import tb4_venv_overlay; tb4_venv_overlay.activate(%s)\n' "'$TB4_BASE_VENV'" \
    > "$site_packages/tb4_venv_overlay.pth"
  # A build folder of its own: a full build's staging folder holds the other packages, which must not be installed.
  build_dir="build/$TB4_ROS_DISTRO-overlay"
  cmake_defines+=(-C "cmake.define.TB4_INTERFACE_PACKAGES=nav2_msgs")
fi
timed "checks and virtual environment"
"$PY" -c 'import sys, pip; sys.exit(0 if tuple(map(int, pip.__version__.split(".")[:2])) >= (23, 1) else 1)' \
  || "$PY" -m pip install -q --upgrade "pip>=23.1"
timed "pip >= 23.1"

install_project() {  # the project, editable, which builds the interface packages and the C kernels
  rm -f "$build_dir"/*/interface-build-times.txt
  "$PY" -m pip install -q --no-build-isolation --no-deps -e ".[all,dev,docs,cluster,foxglove]" "${cmake_defines[@]}" \
    -C "build-dir=$build_dir/{wheel_tag}"
}

install_overlay() {  # only nav2_msgs and the project: the rest is the base environment's
  say "overlaying $TB4_BASE_VENV: building our nav2_msgs ($TB4_ROS_DISTRO wire format) and installing the project"
  install_project
  timed "nav2_msgs, C kernels and the project (pip install -e, builds only)"
}

pip_install() {  # pip install -q ARGS..., from the wheel cache when install_everything found one, else the index
  if [ ${#from_cache[@]} -gt 0 ]; then
    "$PY" -m pip install -q "${from_cache[@]}" "$@" && return 0
    say "installing from the wheel cache failed; from the package index instead"
  fi
  "$PY" -m pip install -q "$@"
}

install_everything() {
  # Requirements come from pyproject.toml (one list each, no copy): the build's, then the project's and every
  # extra's. The build's come first, with cmake and ninja from PyPI so a machine without them still builds; the
  # interface packages then build while the other requirements install beside them (the build is mostly code
  # generation and compiling, pip mostly unpacking and byte-compiling: on two cores they overlap). The second pip is
  # constrained to the versions the first installed, so it never replaces a package the build is using.
  mapfile -t build_reqs < <(requirements build)
  mapfile -t reqs < <(requirements all)
  # Every requirement's wheel, from the wheel cache shared by the machine's clones (tools/wheel_cache.py; filled by
  # `pip wheel` when it has none for these requirements): then both pips install without the network.
  local wheels
  wheels=$("$PY" tools/wheel_cache.py "$PY" "${reqs[@]}" "cmake>=3.22" ninja) || wheels=""
  from_cache=()
  if [ -n "$wheels" ]; then
    from_cache=(--no-index --find-links "$wheels")
    timed "requirement wheels ready in the wheel cache ($wheels)"
  fi
  say "installing the ROS 2 build tools"
  pip_install "${build_reqs[@]}" "cmake>=3.22" ninja
  timed "ROS 2 build tools and message packages (pip)"
  work=$(mktemp -d)
  # (not the project itself when it is installed already: an editable line is no constraint)
  "$PY" -m pip freeze --all | grep -v -e '^-e ' -e ' @ ' > "$work/build-constraints.txt"
  say "installing the ROS 2 wheels and dependencies (in the background, log: $work/pip.log)"
  # At a lower CPU priority: it has time to spare beside the build, which it would otherwise slow down.
  (
    command -v renice > /dev/null && renice -n 10 -p "$BASHPID" > /dev/null 2>&1
    pip_install -c "$work/build-constraints.txt" "${reqs[@]}"
  ) > "$work/pip.log" 2>&1 &
  pip_pid=$!
  # Whatever ends this script ends the background pip too (a failed build, Ctrl-C): the pip, then its subshell.
  stop_background_pip() {
    pkill -P "$pip_pid" 2> /dev/null || true
    kill "$pip_pid" 2> /dev/null || true
    wait "$pip_pid" 2> /dev/null || true
    rm -rf "$work"
  }
  trap stop_background_pip EXIT
  say "building our ROS interfaces ($TB4_ROS_DISTRO wire format) and installing the project (first time: a few minutes)"
  install_project
  timed "interface packages, C kernels and the project (pip install -e, builds only)"
  if ! wait "$pip_pid"; then
    cat "$work/pip.log" >&2
    die "installing the ROS 2 wheels and dependencies failed (its output is above)"
  fi
  trap - EXIT
  rm -rf "$work"
  timed "ROS 2 wheels and dependencies (pip, beside the build: the wait after it)"
}

if [ -n "$TB4_BASE_VENV" ]; then
  install_overlay
else
  install_everything
fi
"$VENV/bin/tb4" doctor >/dev/null || { "$VENV/bin/tb4" doctor; die "the ROS 2 environment is incomplete"; }
timed "tb4 doctor"
say "done; where the time went:"
printf '  %s\n' "${TIMES[@]}"
for times in "$build_dir"/*/interface-build-times.txt; do
  [ -f "$times" ] || continue
  say "interface packages (configure, build and install; packages without dependencies between them overlap):"
  awk '{ printf "  %7.1f s  %s %s\n", $NF, $1, $2 }' "$times"
done
for hit in "$build_dir"/*/interface-cache-hit.txt; do
  [ -f "$hit" ] || continue
  say "interface packages: copied from the build cache, $(cat "$hit") (TB4_INTERFACE_CACHE=off builds them)"
done
