// Compressing the GICP factor of a real scan pair (KITTI 00, frames 0 and 1, 0.25 m voxels): the
// full block, its 29-row exact coreset and its lossless rows (at most 13), with the relative
// errors of H, b and c at the pose the factor was built for (both poses, 12 x 12) and, for the
// lossless rows, at a pose 0.2 m / 2 degrees away. Reads ../shared/data (or --data DIR); when the
// pair is absent it says so and exits with 77 (a skipped test). Prints a report, or one JSON
// object with --json; exits 1 if a check fails.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

#include "carat/base/error.hpp"
#include "carat/coreset/compress.hpp"
#include "carat/registration/align.hpp"
#include "carat/registration/correspondences.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/residuals/lossless_block.hpp"
#include "carat/solver/jacobian_checker.hpp"
#include "carat/solver/se3.hpp"

namespace {

struct Model {
  Eigen::MatrixXd H;
  Eigen::VectorXd b;
  double c = 0.0;
};

Model model_of(const carat::ResidualBlock& block, carat::ParameterPointers params) {
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  carat::evaluate_full_jacobian(block, params, &r, &J);
  return {J.transpose() * J, J.transpose() * r, r.squaredNorm()};
}

double relative(const Model& a, const Model& b) {
  return std::max({(a.H - b.H).norm() / b.H.norm(), (a.b - b.b).norm() / b.b.norm(),
                   std::abs(a.c - b.c) / b.c});
}

}  // namespace

int main(int argc, char** argv) {
  bool json = false;
  const char* env = std::getenv("CARAT_DATA_DIR");
  std::filesystem::path data = env ? env : "../shared/data";
  for (int k = 1; k < argc; ++k) {
    if (std::strcmp(argv[k], "--json") == 0) json = true;
    if (std::strcmp(argv[k], "--data") == 0 && k + 1 < argc) data = argv[++k];
  }
  const std::filesystem::path dir = data / "kitti00_pair";
  if (!std::filesystem::is_regular_file(dir / "000000.bin")) {
    std::printf("skipped: %s not found (the real KITTI pair; pass --data DIR)\n", dir.c_str());
    return 77;
  }
  try {
    carat::PreprocessOptions preprocess;
    preprocess.voxel_size = 0.25;
    const auto target = carat::preprocess_frame(
        carat::read_kitti_bin(dir / "000000.bin", carat::KittiFormat::kXyz), preprocess, "000000");
    const auto source = carat::preprocess_frame(
        carat::read_kitti_bin(dir / "000001.bin", carat::KittiFormat::kXyz), preprocess, "000001");
    const Eigen::Isometry3d T_ij =
        carat::align(target->cloud(), target->tree(), source->cloud(),
                     Eigen::Isometry3d::Identity(), carat::AlignSettings{})
            .T_target_source;
    const auto correspondences =
        carat::find_correspondences(target->cloud(), target->tree(), source->cloud(), T_ij, 1.0);
    const auto full = std::make_shared<carat::GicpBlock>(correspondences, T_ij);
    double xi[7], xj[7];
    carat::se3::to_storage(Eigen::Isometry3d::Identity(), xi);
    carat::se3::to_storage(T_ij, xj);
    const double* at[2] = {xi, xj};
    const auto exact = carat::compress(full, at);
    const auto lossless = carat::make_lossless_block(*full, T_ij);
    const Model reference = model_of(*full, at);
    const double exact_error = relative(model_of(*exact, at), reference);
    const double lossless_error = relative(model_of(*lossless, at), reference);
    carat::se3::Vector6d step;
    step << 0.02, -0.02, 0.03, 0.1, 0.15, -0.05;  // about 0.2 m and 2 degrees
    double moved[7];
    carat::se3::to_storage(T_ij * carat::se3::exp(step), moved);
    const double* away[2] = {xi, moved};
    const double lossless_away = relative(model_of(*lossless, away), model_of(*full, away));
    const double exact_away = relative(model_of(*exact, away), model_of(*full, away));
    const bool ok = exact->num_rows() == 29 && exact_error < 1e-10 && lossless_error < 1e-10 &&
                    lossless_away < 1e-10;
    if (json) {
      std::printf(
          "{\n  \"correspondences\": %zu,\n  \"full_rows\": %d,\n  \"full_bytes\": %zu,\n"
          "  \"exact_rows\": %d,\n  \"exact_bytes\": %zu,\n  \"lossless_rows\": %d,\n"
          "  \"lossless_bytes\": %zu,\n  \"exact_error\": %.3e,\n  \"lossless_error\": %.3e,\n"
          "  \"exact_error_away\": %.3e,\n  \"lossless_error_away\": %.3e,\n  \"ok\": %s\n}\n",
          correspondences.size(), full->num_rows(), full->memory_bytes(), exact->num_rows(),
          exact->memory_bytes(), lossless->num_rows(), lossless->memory_bytes(), exact_error,
          lossless_error, exact_away, lossless_away, ok ? "true" : "false");
    } else {
      std::printf("GICP factor of KITTI 00 frames 0-1: %zu correspondences, %d rows, %zu bytes\n",
                  correspondences.size(), full->num_rows(), full->memory_bytes());
      std::printf(
          "  exact coreset : %2d rows, %6zu bytes, H/b/c error %.1e here, %.1e 0.2 m away\n",
          exact->num_rows(), exact->memory_bytes(), exact_error, exact_away);
      std::printf(
          "  lossless rows : %2d rows, %6zu bytes, H/b/c error %.1e here, %.1e 0.2 m away\n",
          lossless->num_rows(), lossless->memory_bytes(), lossless_error, lossless_away);
      std::printf("%s\n", ok ? "ok" : "FAILED");
    }
    return ok ? 0 : 1;
  } catch (const carat::Error& e) {
    std::fprintf(stderr, "gicp_compression: %s\n", e.what());
    return 1;
  }
}
