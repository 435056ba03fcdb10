#pragma once

// A progress bar on stderr for stages that take more than a second, shown only when stderr is
// a terminal (never in pipes, files or tests). Safe to update from several threads.

#include <unistd.h>

#include <cstdio>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

#include "carat/base/stopwatch.hpp"

namespace carat::cli {

/// One stage's progress bar; erased by finish() or the destructor.
class ProgressBar {
 public:
  /// A bar labelled `label`; silent unless stderr is a terminal and `enabled`.
  explicit ProgressBar(std::string label, bool enabled = true)
      : label_(std::move(label)), enabled_(enabled && isatty(STDERR_FILENO) == 1) {}
  ~ProgressBar() { finish(); }
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  /// Reports `done` of `total`; draws at most 10 times a second, after the first second.
  void update(std::size_t done, std::size_t total) {
    if (!enabled_) return;
    std::lock_guard lock(mutex_);
    if (since_start_.elapsed_s() < 1.0 || since_draw_.elapsed_s() < 0.1) return;
    since_draw_.restart();
    const int width = 30;
    const int filled = total == 0 ? width : static_cast<int>(width * done / total);
    std::fprintf(stderr, "\r%-28s [%s%s] %zu/%zu", label_.c_str(), std::string(filled, '#').c_str(),
                 std::string(width - filled, ' ').c_str(), done, total);
    std::fflush(stderr);
    drawn_ = true;
  }
  /// A callback for library functions that report (done, total).
  auto callback() {
    return [this](std::size_t done, std::size_t total) { update(done, total); };
  }
  /// Erases the bar if it was drawn.
  void finish() {
    std::lock_guard lock(mutex_);
    if (drawn_) std::fprintf(stderr, "\r%80s\r", "");
    drawn_ = false;
  }

 private:
  std::string label_;
  bool enabled_;
  bool drawn_ = false;
  Stopwatch since_start_;  // the first draw waits a second
  Stopwatch since_draw_;   // then at most one draw per 0.1 s
  std::mutex mutex_;
};

/// One bar per stage of a pipeline whose progress callback names the stage: stages run one after
/// the other, a stage's reports may come from any thread. The bar in view is erased by finish()
/// or the destructor.
template <typename Stage>
class StageBars {
 public:
  /// Bars labelled by `label(stage)`; silent unless stderr is a terminal and `enabled`.
  StageBars(std::function<std::string(Stage)> label, bool enabled)
      : state_(std::make_shared<State>()) {
    state_->label = std::move(label);
    state_->enabled = enabled;
  }
  ~StageBars() { finish(); }
  StageBars(const StageBars&) = delete;
  StageBars& operator=(const StageBars&) = delete;

  /// The (stage, done, total) callback for the pipeline.
  std::function<void(Stage, std::size_t, std::size_t)> callback() {
    return [state = state_](Stage stage, std::size_t done, std::size_t total) {
      const std::lock_guard<std::mutex> lock(state->mutex);
      if (!state->bar || stage != state->shown) {
        state->bar.reset();
        state->bar = std::make_unique<ProgressBar>(state->label(stage), state->enabled);
        state->shown = stage;
      }
      state->bar->update(done, total);
    };
  }
  /// Erases the bar in view.
  void finish() {
    const std::lock_guard<std::mutex> lock(state_->mutex);
    state_->bar.reset();
  }

 private:
  struct State {
    std::function<std::string(Stage)> label;
    bool enabled = true;
    std::mutex mutex;
    std::unique_ptr<ProgressBar> bar;
    Stage shown{};
  };
  std::shared_ptr<State> state_;
};

}  // namespace carat::cli
