// The carat Python module (carat._carat; carat/__init__.py re-exports it).
#include <pybind11/pybind11.h>

#include "bindings.hpp"
#include "carat/base/error.hpp"
#include "carat/base/version.hpp"

PYBIND11_MODULE(_carat, m) {
  namespace py = pybind11;
  m.doc() = "carat: sparse nonlinear least squares with exact residual-block compression";
  m.attr("__version__") = carat::version();
  // carat's errors (bad input, files, options) keep their one-line message.
  py::register_exception<carat::Error>(m, "Error", PyExc_RuntimeError);
  carat::python::bind_coreset(m);
  carat::python::bind_clouds(m);
  carat::python::bind_registration(m);
  carat::python::bind_mapping(m);
  carat::python::bind_solve(m);
  carat::python::bind_problem(m);
  carat::python::bind_sim(m);
}
