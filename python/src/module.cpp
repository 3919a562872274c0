// hydrojet._core: the ROS-free core (rod solver, controller, simulated plant, experiment runs) for
// Python. The package hydrojet (python/hydrojet) wraps it; this module is its private half.
#include <nanobind/nanobind.h>

#include "bindings.h"
#include "hydrojet_control/config/yaml_tree.h"

NB_MODULE(_core, m) {
  m.doc() = "hydrojet_control's ROS-free core: rod solver, controller, simulated plant";
  // A configuration error (scene, plant, controller options: each names its key) is a ValueError,
  // as the command lines report it with exit status 2.
  nanobind::register_exception_translator([](const std::exception_ptr& p, void*) {
    try {
      std::rethrow_exception(p);
    } catch (const hydrojet::config::KeyError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });
  hydrojet::python::bind_scene(m);
  hydrojet::python::bind_loop(m);
  hydrojet::python::bind_env(m);
}
