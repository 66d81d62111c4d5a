# shellcheck shell=bash
# Source me (bash):  source scripts/env.sh
# Activates .venv (create it first: scripts/bootstrap.sh or `make venv`) and sets the ROS 2
# environment every flex-twin process needs BEFORE rclpy is imported:
#   ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST  never discover/multicast beyond this host
#   ROS_DOMAIN_ID is left as the user has it (unset: ROS's default 0), so nodes started in
#   separate terminals and a system ros2 CLI see each other; tests and CI pick their own.
#   RMW_IMPLEMENTATION=rmw_fastrtps_cpp      the only RMW the wheels ship
#   AMENT_PREFIX_PATH=$VIRTUAL_ENV           rclpy pub/sub works without it, but ament_index
#                                            (get_package_share_directory, ...) raises if unset
_flex_twin_root="$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")/.." && pwd)"
if [ ! -x "$_flex_twin_root/.venv/bin/python" ]; then
  echo "env.sh: $_flex_twin_root/.venv missing; run scripts/bootstrap.sh (or make venv)" >&2
  unset _flex_twin_root
  return 1 2>/dev/null || exit 1
fi
case "$-" in *i*) ;; *) VIRTUAL_ENV_DISABLE_PROMPT=1 ;; esac
# shellcheck disable=SC1091
. "$_flex_twin_root/.venv/bin/activate"
unset _flex_twin_root

export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export RMW_IMPLEMENTATION=rmw_fastrtps_cpp
export AMENT_PREFIX_PATH="$VIRTUAL_ENV"
# Deprecated in Jazzy in favour of ROS_AUTOMATIC_DISCOVERY_RANGE; drop it to avoid mixed signals.
unset ROS_LOCALHOST_ONLY
