# Source me (bash or zsh):   source scripts/env.sh
# Activates .venv (ROS 2 Jazzy from PyPI wheels) and overlays the colcon workspace install/,
# so that `import itasc_msgs.msg`, our packages, ament_index_python and the executables
# under install/<pkg>/lib/<pkg>/ work. Defines `ros2run <pkg> <executable> [args...]`, a
# stand-in for `ros2 run` (there is no ros2 CLI on PyPI).
# Run `make setup` (scripts/setup.sh) first.

if [ -n "${BASH_VERSION:-}" ]; then
  _itasc_env_file="${BASH_SOURCE[0]}"
elif [ -n "${ZSH_VERSION:-}" ]; then
  _itasc_env_file="${(%):-%x}"
else
  _itasc_env_file="${0}"
fi
ITASC_ROOT="$(cd "$(dirname "$_itasc_env_file")/.." && pwd)"
export ITASC_ROOT
unset _itasc_env_file

if [ ! -x "$ITASC_ROOT/.venv/bin/python" ] || [ ! -f "$ITASC_ROOT/install/setup.sh" ]; then
  echo "scripts/env.sh: $ITASC_ROOT/.venv or install/ missing; run 'make setup' first" >&2
  return 1 2>/dev/null || exit 1
fi

# colcon's and the venv's scripts are not written for `set -u`; restore the caller's mode after.
case $- in *u*) _itasc_nounset=1; set +u ;; *) _itasc_nounset=0 ;; esac

# 1. The venv. Its prefix is itself an ament prefix: the ROS wheels install
#    share/ament_index/, share/<pkg>/cmake and lib/*.so under .venv.
. "$ITASC_ROOT/.venv/bin/activate"
_itasc_venv="$ITASC_ROOT/.venv"
_itasc_site="$_itasc_venv/lib/python3.12/site-packages"

_itasc_prepend() {  # _itasc_prepend VAR DIR: put DIR first in VAR, once
  eval "_itasc_cur=\"\${$1:-}\""
  case ":$_itasc_cur:" in
    *":$2:"*) ;;
    *) eval "export $1=\"$2\${_itasc_cur:+:\$_itasc_cur}\"" ;;
  esac
  unset _itasc_cur
}

# 2. What the wheel `ros-wheels-bootstrapper` would do: its .pth hook re-execs every Python
#    start with LD_LIBRARY_PATH += <venv>/lib and site-packages/ros_*.libs (the shared
#    libraries of rcl, rmw, Fast DDS and the message packages). We set the same here, once,
#    and set its guard variable so that Python starts do not pay for a re-exec.
for _itasc_d in "$_itasc_site"/ros_*.libs; do
  [ -d "$_itasc_d" ] && _itasc_prepend LD_LIBRARY_PATH "$_itasc_d"
done
_itasc_prepend LD_LIBRARY_PATH "$_itasc_venv/lib"
export _ROS_WHEELS_BOOTSTRAP_COMPLETE=1
# ament_index_python / rmw_implementation look packages up through AMENT_PREFIX_PATH; the
# ROS CMake configs through CMAKE_PREFIX_PATH.
_itasc_prepend AMENT_PREFIX_PATH "$_itasc_venv"
_itasc_prepend CMAKE_PREFIX_PATH "$_itasc_venv"

# 3. The workspace overlay (adds install/<pkg> to AMENT_PREFIX_PATH, PYTHONPATH,
#    LD_LIBRARY_PATH for libitasc_msgs__*.so, CMAKE_PREFIX_PATH).
if [ -n "${ZSH_VERSION:-}" ] && [ -f "$ITASC_ROOT/install/setup.zsh" ]; then
  . "$ITASC_ROOT/install/setup.zsh"
elif [ -n "${BASH_VERSION:-}" ] && [ -f "$ITASC_ROOT/install/setup.bash" ]; then
  . "$ITASC_ROOT/install/setup.bash"
else
  COLCON_CURRENT_PREFIX="$ITASC_ROOT/install" . "$ITASC_ROOT/install/setup.sh"
fi

# 4. ROS defaults for this project (each only if not set by the caller).
#    Fast DDS is the only RMW the wheels ship.
export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"
#    Discovery stays on this machine: no traffic to the LAN from demos or tests (our executables
#    implement LOCALHOST with a UDP-only Fast DDS profile, see itasc_core/communication/dds.py).
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
#    Node logs under the git-ignored log/ instead of ~/.ros/log.
export ROS_LOG_DIR="${ROS_LOG_DIR:-$ITASC_ROOT/log/ros}"

unset _itasc_d _itasc_venv _itasc_site
unset -f _itasc_prepend
[ "$_itasc_nounset" = 1 ] && set -u
unset _itasc_nounset

# ros2run <package> <executable> [args...]: like `ros2 run`, finds the package's prefix in
# AMENT_PREFIX_PATH (ament resource index) and runs <prefix>/lib/<package>/<executable>.
ros2run() {
  if [ $# -lt 2 ]; then
    echo "usage: ros2run <package> <executable> [args...]" >&2
    return 2
  fi
  local pkg="$1" exe="$2" prefix found="" IFS=:
  shift 2
  for prefix in $AMENT_PREFIX_PATH; do
    if [ -f "$prefix/share/ament_index/resource_index/packages/$pkg" ]; then
      found="$prefix"; break
    fi
  done
  unset IFS
  if [ -z "$found" ]; then
    echo "ros2run: package '$pkg' not found in AMENT_PREFIX_PATH" >&2
    return 1
  fi
  if [ ! -x "$found/lib/$pkg/$exe" ]; then
    echo "ros2run: no executable '$exe' in package '$pkg' ($found/lib/$pkg/)" >&2
    return 1
  fi
  "$found/lib/$pkg/$exe" "$@"
}
