# devel_parents DEVEL: the workspaces a catkin devel space chains to (catkin records them in its
# _setup_util.py at configure time), one per line, besides itself and the system's (/usr, and
# /opt/ros/noetic of other distributions). Empty when it chains to none. Sourced by scripts/build
# and scripts/lib/check_tree.sh.
devel_parents() {
  sed -n "s/^ *CMAKE_PREFIX_PATH = r\?'\(.*\)'\.split.*/\1/p" "$1/_setup_util.py" 2>/dev/null | tr ';' '\n' |
    grep -v -x -e "$1" -e /usr -e /opt/ros/noetic -e '' || true
}
