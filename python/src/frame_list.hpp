#pragma once

/// Lists of carat::Frame objects passed from Python.

#include <pybind11/pybind11.h>

#include <memory>
#include <string>
#include <vector>

#include "carat/registration/frame.hpp"

namespace carat::python {

/// The frames of a Python sequence of carat.Frame; TypeError naming `what` and the position of
/// an element that is not a Frame.
std::vector<std::shared_ptr<const Frame>> frames_from_sequence(const pybind11::handle& obj,
                                                               const std::string& what);

/// A Python list of carat.Frame sharing the frames.
pybind11::list list_from_frames(const std::vector<std::shared_ptr<const Frame>>& frames);

}  // namespace carat::python
