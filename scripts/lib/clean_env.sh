# Sourced first by every script that builds, tests or judges: runs the script again in a clean
# environment, so that it behaves the same from a shell that sourced a devel space (whose
# LD_LIBRARY_PATH would beat the trees' RUNPATH and load another tree's libraries, and whose
# CMAKE_PREFIX_PATH would make another tree a parent workspace), from `env -i`, and in CI.
# Kept: the user's identity, locale, terminal and display, proxies, CI, and the project's own
# switches (HYDROJET_*). Everything else (LD_LIBRARY_PATH, LD_PRELOAD, PYTHONPATH, ROS_*,
# CMAKE_PREFIX_PATH, ASAN_/UBSAN_/LSAN_OPTIONS, ...) is dropped; PATH is the system's.
if [ -z "$HYDROJET_CLEAN_ENV" ]; then
  _hj_keep=()
  for _hj_name in HOME USER LOGNAME LANG LC_ALL TERM DISPLAY XAUTHORITY TMPDIR CI \
    http_proxy https_proxy no_proxy HTTP_PROXY HTTPS_PROXY NO_PROXY $(compgen -e | grep '^HYDROJET_'); do
    [ -n "${!_hj_name+set}" ] && _hj_keep+=("$_hj_name=${!_hj_name}")
  done
  exec env -i "${_hj_keep[@]}" HYDROJET_CLEAN_ENV=1 \
    PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin bash "$0" "$@"
fi
