# Installs carat into WORK_DIR/prefix, then builds and runs examples/consumer (the whole package)
# and examples/consumer_solver (COMPONENTS solver) against it.
file(REMOVE_RECURSE "${WORK_DIR}")
execute_process(COMMAND ${CMAKE_COMMAND} --install "${CARAT_BINARY_DIR}" --prefix "${WORK_DIR}/prefix"
                RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cmake --install failed (${rc})")
endif()
# consumer: the whole package (carat::carat); consumer_solver: COMPONENTS solver, configured
# with the header-only libraries it must not need made unfindable.
foreach(project consumer consumer_solver)
  set(extra)
  if(project STREQUAL "consumer_solver")
    set(extra -DCMAKE_DISABLE_FIND_PACKAGE_nlohmann_json=ON -DCMAKE_DISABLE_FIND_PACKAGE_nanoflann=ON)
  endif()
  execute_process(COMMAND ${CMAKE_COMMAND} -S "${CARAT_SOURCE_DIR}/examples/${project}"
                          -B "${WORK_DIR}/${project}" -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix
                          -DCMAKE_BUILD_TYPE=Release ${extra}
                  RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "configuring ${project} against the installed package failed (${rc})")
  endif()
  execute_process(COMMAND ${CMAKE_COMMAND} --build "${WORK_DIR}/${project}" RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "building ${project} failed (${rc})")
  endif()
  execute_process(COMMAND "${WORK_DIR}/${project}/${project}" RESULT_VARIABLE rc OUTPUT_VARIABLE out)
  message("${out}")
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${project} failed (${rc})")
  endif()
  if(NOT out MATCHES "${project}: ok")
    message(FATAL_ERROR "${project} did not report success")
  endif()
endforeach()

# The Python package, when it is built: installed under the prefix (a relative
# CARAT_PYTHON_INSTALL_DIR), it imports from there and computes.
if(PYTHON)
  if(IS_ABSOLUTE "${PYTHON_INSTALL_DIR}")
    message(FATAL_ERROR "CARAT_PYTHON_INSTALL_DIR is outside the prefix (${PYTHON_INSTALL_DIR}): "
                        "this test installs into a scratch prefix only")
  endif()
  set(site "${WORK_DIR}/prefix/${PYTHON_INSTALL_DIR}")
  execute_process(COMMAND ${CMAKE_COMMAND} -E env PYTHONPATH=${site} ${PYTHON} -c
                          "import carat, numpy as np; assert carat.__file__.startswith('${site}'), carat.__file__; J = np.random.default_rng(0).normal(size=(500, 6)); e = np.ones(500); i, w = carat.coreset(J, e); assert np.allclose((J[i].T * w) @ J[i], J.T @ J); print('python: ok', carat.__version__)"
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  message("${out}${err}")
  if(NOT rc EQUAL 0 OR NOT out MATCHES "python: ok")
    message(FATAL_ERROR "the installed Python package did not import and compute (${rc})")
  endif()
endif()

# An unknown component is refused by name.
file(WRITE "${WORK_DIR}/unknown/CMakeLists.txt"
     "cmake_minimum_required(VERSION 3.25)\nproject(unknown LANGUAGES CXX)\n"
     "find_package(carat CONFIG REQUIRED COMPONENTS solver teleport)\n")
execute_process(COMMAND ${CMAKE_COMMAND} -S "${WORK_DIR}/unknown" -B "${WORK_DIR}/unknown/build"
                        -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc EQUAL 0)
  message(FATAL_ERROR "find_package(carat COMPONENTS teleport) succeeded")
endif()
if(NOT "${out}${err}" MATCHES "teleport")
  message(FATAL_ERROR "the error for an unknown component does not name it:\n${out}${err}")
endif()
