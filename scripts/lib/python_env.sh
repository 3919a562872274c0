# Sourced by the scripts that use the Python face: hydrojet_pip_install builds and installs the
# package into .venv (scripts/setup made it) with `pip install .`. The core is compiled in its own
# tree, .build-python (static, position-independent, no ROS), kept between runs so that a second
# install recompiles only what changed; the catkin trees are not touched.
hydrojet_pip_install() {
  CMAKE_BUILD_PARALLEL_LEVEL=$(nproc) .venv/bin/pip install -q --no-build-isolation --no-deps . \
    --config-settings=build-dir=.build-python
}
