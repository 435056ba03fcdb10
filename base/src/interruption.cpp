#include "carat/base/interruption.hpp"

#include <utility>

namespace carat {
namespace {

thread_local const std::function<void()>* installed = nullptr;

}  // namespace

InterruptionScope::InterruptionScope(std::function<void()> check)
    : check_(std::move(check)), previous_(installed) {
  installed = &check_;
}

InterruptionScope::~InterruptionScope() { installed = previous_; }

void interruption_point() {
  if (installed != nullptr && *installed) (*installed)();
}

}  // namespace carat
