// The carat Python module (carat._carat; carat/__init__.py re-exports it).
#include <pybind11/pybind11.h>

#include "bindings.hpp"
#include "carat/base/blas_kernels.hpp"
#include "carat/base/error.hpp"
#include "carat/base/version.hpp"

PYBIND11_MODULE(_carat, m) {
  namespace py = pybind11;
  m.doc() = "carat: sparse nonlinear least squares with exact residual-block compression";
  m.attr("__version__") = carat::version();
  // carat's errors (bad input, files, options) keep their one-line message.
  m.def(
      "blas_kernels",
      [] {
        const carat::BlasKernels k = carat::blas_kernels();
        py::dict out;
        out["library"] = k.library;
        out["core"] = k.core;
        out["suggested_core"] = k.suggested_core;
        return out;
      },
      "The BLAS kernels this process runs: dict(library, core, suggested_core). A non-empty "
      "suggested_core means OpenBLAS fell back to its oldest x86-64 kernels on this CPU: set "
      "OPENBLAS_CORETYPE to it before Python starts (the factorizations run several times "
      "faster).");
  py::register_exception<carat::Error>(m, "Error", PyExc_RuntimeError);
  carat::python::bind_coreset(m);
  carat::python::bind_clouds(m);
  carat::python::bind_registration(m);
  carat::python::bind_mapping(m);
  carat::python::bind_solve(m);
  carat::python::bind_problem(m);
  carat::python::bind_sim(m);
}
