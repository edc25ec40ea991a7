#!/usr/bin/env bash
# Set up the development environment of iTaSC-ROS2, idempotently:
#   1. .venv/ with CPython 3.12 (the ROS 2 Jazzy wheels on PyPI exist for 3.12 only),
#   2. pinned requirements/runtime.txt + requirements/test.txt, and the test suite's package of kinds
#      (test/plugins/itasc_test_kinds, editable),
#   3. a venv-local fix of the ROS wheels' exported CMake targets (see fix_cmake_exports),
#   4. `colcon build --symlink-install` of every package into install/.
# Each step is skipped when its stamp (a hash of its inputs) is unchanged, so a no-op run
# takes well under a second.
#
# Usage: scripts/setup.sh            # steps 1-4
#        scripts/setup.sh --bench    # also requirements/bench.txt
#        scripts/setup.sh --force    # ignore stamps
# Env:   PYTHON312=/path/to/python3.12 to choose the interpreter.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
STAMPS="$VENV/.itasc-stamps"
BUILD_STAMP="$ROOT/install/.itasc-build-stamp"
WITH_BENCH=0
FORCE=0
for arg in "$@"; do
  case "$arg" in
    --bench) WITH_BENCH=1 ;;
    --force) FORCE=1 ;;
    -h|--help) sed -n '2,15p' "$0"; exit 0 ;;
    *) echo "setup.sh: unknown argument '$arg'" >&2; exit 2 ;;
  esac
done

log() { printf '[setup] %s\n' "$*"; }
die() { printf '[setup] ERROR: %s\n' "$*" >&2; exit 1; }

# Hash of a list of files (contents and names); missing files hash as their name only.
hash_files() {
  local f
  for f in "$@"; do
    printf '%s\n' "${f#"$ROOT"/}"
    if [ -f "$f" ]; then sha256sum < "$f"; fi
  done | sha256sum | cut -c1-16
}

stamp_ok() {  # stamp_ok <file> <key>
  [ "$FORCE" = 0 ] && [ -f "$1" ] && [ "$(cat "$1")" = "$2" ]
}

# ---------------------------------------------------------------- 1. find CPython 3.12
is_py312() {  # prints the real interpreter path if "$@" runs a CPython 3.12
  "$@" -c 'import sys; assert sys.version_info[:2] == (3, 12) and sys.implementation.name == "cpython"; print(sys.executable)' 2>/dev/null
}

find_python312() {
  local exe v cand
  if [ -n "${PYTHON312:-}" ]; then
    exe="$(is_py312 "$PYTHON312")" || die "PYTHON312=$PYTHON312 is not a working CPython 3.12"
    echo "$exe"; return
  fi
  # a) python3.12 on PATH (may be a pyenv shim that fails without a selected version)
  if command -v python3.12 >/dev/null 2>&1 && exe="$(is_py312 python3.12)"; then echo "$exe"; return; fi
  # b) pyenv: select an installed 3.12.x through PYENV_VERSION
  if command -v pyenv >/dev/null 2>&1; then
    for v in $(pyenv versions --bare 2>/dev/null | grep -E '^3\.12(\.[0-9]+)?$' | sort -rV); do
      if exe="$(PYENV_VERSION="$v" is_py312 python3.12)"; then echo "$exe"; return; fi
    done
  fi
  # c) pyenv install trees without a working pyenv, then usual system locations
  for cand in "${PYENV_ROOT:-$HOME/.pyenv}"/versions/3.12*/bin/python3.12 \
              /root/.pyenv/versions/3.12*/bin/python3.12 \
              /usr/local/bin/python3.12 /usr/bin/python3.12 /opt/python3.12/bin/python3.12; do
    [ -x "$cand" ] || continue
    if exe="$(is_py312 "$cand")"; then echo "$exe"; return; fi
  done
  # d) a plain python3 that happens to be 3.12; uv-managed interpreters if uv is there
  if command -v python3 >/dev/null 2>&1 && exe="$(is_py312 python3)"; then echo "$exe"; return; fi
  if command -v uv >/dev/null 2>&1 && cand="$(uv python find 3.12 2>/dev/null)" \
     && exe="$(is_py312 "$cand")"; then echo "$exe"; return; fi
  die "no CPython 3.12 found (the ROS 2 Jazzy wheels need exactly 3.12).
  Tried: python3.12 on PATH, pyenv versions 3.12.x (PYENV_VERSION), ${PYENV_ROOT:-$HOME/.pyenv}/versions/3.12*/bin/python3.12,
  /usr/local/bin/python3.12, /usr/bin/python3.12, python3, uv.
  Install one (e.g. 'pyenv install 3.12' or 'apt-get install python3.12 python3.12-venv') or set PYTHON312=/path/to/python3.12."
}

# ---------------------------------------------------------------- 2. venv + requirements
REQ_FILES=("$ROOT/requirements/runtime.txt" "$ROOT/requirements/test.txt" "$ROOT/requirements/constraints.txt")
for f in "${REQ_FILES[@]}"; do [ -f "$f" ] || die "missing $f"; done

if [ ! -x "$VENV/bin/python" ] || ! is_py312 "$VENV/bin/python" >/dev/null; then
  PY="$(find_python312)"
  log "creating .venv with $PY"
  rm -rf "$VENV"
  "$PY" -m venv "$VENV" || die "'$PY -m venv' failed (Debian: apt-get install python3.12-venv)"
fi
VPY="$VENV/bin/python"
# Let the venv's own ROS wheels re-exec hook (ros_wheels_bootstrapper) do its job in child
# processes: do not inherit a guard from an outer, possibly different, environment.
unset _ROS_WHEELS_BOOTSTRAP_COMPLETE

REQ_KEY="$(hash_files "${REQ_FILES[@]}")"
if ! stamp_ok "$STAMPS/requirements" "$REQ_KEY"; then
  log "installing requirements/runtime.txt + requirements/test.txt (pinned)"
  "$VPY" -m pip install --disable-pip-version-check -q \
    -r "$ROOT/requirements/runtime.txt" -r "$ROOT/requirements/test.txt"
  mkdir -p "$STAMPS" && echo "$REQ_KEY" > "$STAMPS/requirements"
  rm -f "$BUILD_STAMP"   # the build depends on the venv
fi

# The test suite's package of kinds from outside the source tree (test/plugins/itasc_test_kinds):
# a task type and a Monitor condition the project finds through their entry points only.
KINDS_DIR="$ROOT/test/plugins/itasc_test_kinds"
KINDS_KEY="$(hash_files $(find "$KINDS_DIR" -name '*.py' -o -name '*.toml' | LC_ALL=C sort))"
if ! stamp_ok "$STAMPS/test-kinds" "$KINDS_KEY"; then
  log "installing test/plugins/itasc_test_kinds (editable)"
  "$VPY" -m pip install --disable-pip-version-check -q --no-deps --no-build-isolation -e "$KINDS_DIR"
  mkdir -p "$STAMPS" && echo "$KINDS_KEY" > "$STAMPS/test-kinds"
fi

if [ "$WITH_BENCH" = 1 ]; then
  BENCH_KEY="$(hash_files "$ROOT/requirements/bench.txt" "$ROOT/requirements/constraints.txt")"
  if ! stamp_ok "$STAMPS/bench" "$BENCH_KEY"; then
    log "installing requirements/bench.txt"
    "$VPY" -m pip install --disable-pip-version-check -q -r "$ROOT/requirements/bench.txt"
    echo "$BENCH_KEY" > "$STAMPS/bench"
  fi
fi

# graphviz's `dot` renders the graphs of `make graph`; optional, never fatal.
if ! command -v dot >/dev/null 2>&1 && [ ! -f "$STAMPS/graphviz-tried" ]; then
  mkdir -p "$STAMPS"; touch "$STAMPS/graphviz-tried"
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    log "installing graphviz (dot) with apt-get"
    { apt-get install -y -q --no-install-recommends graphviz >/dev/null 2>&1 \
      || { apt-get update -q >/dev/null 2>&1 && apt-get install -y -q --no-install-recommends graphviz >/dev/null 2>&1; }; } \
      || log "warning: could not install graphviz; 'make graph' will only write .dot files"
  else
    log "note: graphviz 'dot' not found and not root; 'make graph' will only write .dot files"
  fi
fi

# ---------------------------------------------------------------- 3. CMake export fix
# The ROS wheels were built in a manylinux image with CPython at /opt/python/cp312-cp312. Their
# exported CMake targets (share/<pkg>/cmake/export_<pkg>__rosidl_generator_pyExport.cmake, e.g.
# builtin_interfaces::builtin_interfaces__rosidl_generator_py) still list, in
# INTERFACE_INCLUDE_DIRECTORIES, that interpreter's include dir and its numpy's include dir.
# CMake refuses to generate any package that links those targets (our itasc_msgs does) while
# those directories do not exist. We rewrite the paths, in this venv's copies only, to the
# include dir of the interpreter that backs the venv and to numpy.get_include() of the venv's
# numpy: these are the headers the extension we build is actually compiled against. We do not
# create /opt/python/... on the machine: that would need root, touch the system outside the
# repo and point CMake at headers of no interpreter that exists here. pip reinstalling a ROS
# wheel restores the original files, so this runs after every install and before every build.
fix_cmake_exports() {
  "$VPY" - "$VENV" <<'PYEOF'
import os, re, sys, sysconfig
import numpy
venv = sys.argv[1]
py_inc = sysconfig.get_paths()["include"]
np_inc = numpy.get_include()
for d in (py_inc, np_inc):
    if not os.path.isdir(d):
        sys.exit(f"[setup] ERROR: include dir {d} does not exist (python headers missing?)")
manylinux = r"/opt/python/cp3\d+-cp3\d+t?"
subs = [
    (re.compile(manylinux + r"/lib/python3\.\d+t?/site-packages/numpy/(?:_core|core)/include"), np_inc),
    (re.compile(manylinux + r"/include/python3\.\d+t?"), py_inc),
]
roots = [os.path.join(venv, "share"), os.path.join(venv, "lib", "cmake")]
changed, leftover = 0, []
for root in roots:
    for dirpath, _, files in os.walk(root):
        for name in files:
            if not name.endswith(".cmake"):
                continue
            path = os.path.join(dirpath, name)
            with open(path, encoding="utf-8", errors="surrogateescape") as f:
                text = f.read()
            if "/opt/python/" not in text:
                continue
            new = text
            for rx, repl in subs:
                new = rx.sub(lambda _m, r=repl: r, new)
            if new != text:
                tmp = path + ".itasc-tmp"
                with open(tmp, "w", encoding="utf-8", errors="surrogateescape") as f:
                    f.write(new)
                os.replace(tmp, path)
                changed += 1
            if "/opt/python/" in new:
                leftover.append(path)
if changed:
    print(f"[setup] rewrote manylinux include dirs in {changed} CMake export files -> {py_inc}, {np_inc}")
for path in leftover:
    print(f"[setup] warning: {path} still mentions /opt/python/ (unknown pattern)")
PYEOF
}

# ---------------------------------------------------------------- 4. colcon build
# Inputs of the build: package manifests and interface definitions, and the list of files
# under config/ (installed one symlink per file into share/itasc_bringup/config). Python
# modules are not inputs: with --symlink-install they are used in place.
build_inputs() {
  local d
  for d in "$ROOT/src" "$ROOT/bringup" "$ROOT/vendor"; do
    [ -d "$d" ] || continue
    find "$d" -maxdepth 3 \( -name __pycache__ -o -name '*.egg-info' \) -prune -o -type f \
      \( -name package.xml -o -name setup.py -o -name setup.cfg -o -name CMakeLists.txt \
         -o -name '*.msg' -o -name '*.srv' -o -name '*.action' -o -path '*/resource/*' \
         -o -name COLCON_IGNORE -o -name AMENT_IGNORE \) -print
  done | LC_ALL=C sort
  echo "$ROOT/scripts/setup.sh"
}
# tf2_msgs (the type of /tf) has no PyPI wheel: vendor/tf2_msgs, Jazzy's interface files, is
# built with the workspace only when no tf2_msgs is installed (the venv, or a sourced ROS 2
# install); it never shadows a real one. Outside our own install/, which it may be in already.
BASE_PATHS=(src bringup)
tf2_msgs_installed() {
  local prefix IFS=:
  for prefix in $VENV ${AMENT_PREFIX_PATH:-}; do
    case "$prefix" in "$ROOT/install"|"$ROOT/install/"*) continue ;; esac
    [ -f "$prefix/share/ament_index/resource_index/packages/tf2_msgs" ] && return 0
  done
  return 1
}
tf2_msgs_installed || BASE_PATHS+=(vendor)

BUILD_KEY="$( { hash_files $(build_inputs); echo "$REQ_KEY" "${BASE_PATHS[*]}";
               [ -d "$ROOT/config" ] && (cd "$ROOT" && find -L config -type f -not -path '*/__pycache__/*' | LC_ALL=C sort);
               true; } | sha256sum | cut -c1-16)"

# The bytecode of our modules (used in place, --symlink-install), written here: where
# PYTHONDONTWRITEBYTECODE is set, as on these machines, every process would otherwise compile
# them anew as it starts (each bootstrap, composite and visualization process). Up to date: ~0.1 s.
compile_sources() {
  "$VENV/bin/python" -m compileall -q "$ROOT/src" "$ROOT/bringup" >/dev/null \
    || log "warning: python -m compileall failed; the modules are compiled as they are imported"
}

if stamp_ok "$BUILD_STAMP" "$BUILD_KEY" && [ -f "$ROOT/install/setup.bash" ]; then
  compile_sources
  exit 0
fi

fix_cmake_exports
log "colcon build --symlink-install (${BASE_PATHS[*]}) -> install/"
(
  cd "$ROOT"
  # colcon, cmake, the rosidl generators and setup.py must all use the venv's python.
  export VIRTUAL_ENV="$VENV"
  export PATH="$VENV/bin:$PATH"
  export CMAKE_PREFIX_PATH="$VENV${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}"
  export AMENT_PREFIX_PATH="$VENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
  export COLCON_LOG_PATH="$ROOT/log"
  unset PYTHONPATH
  "$VENV/bin/colcon" build \
    --base-paths "${BASE_PATHS[@]}" \
    --build-base build --install-base install \
    --symlink-install \
    --parallel-workers 2 \
    --cmake-args -DBUILD_TESTING=OFF \
      -DPython3_EXECUTABLE="$VENV/bin/python" -DPython3_FIND_VIRTUALENV=ONLY \
      -DCMAKE_BUILD_TYPE=Release
) || die "colcon build failed (see the output above and log/latest_build/)"
echo "$BUILD_KEY" > "$BUILD_STAMP"
compile_sources
log "done: source scripts/env.sh to use the workspace"
