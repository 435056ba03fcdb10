#include "carat/sim/bal_scene.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include "carat/base/error.hpp"
#include "carat/residuals/snavely_camera.hpp"
#include "random.hpp"

namespace carat {
namespace {

using sim_detail::Random;

constexpr double kRingRadius = 10.0;       // metres
constexpr double kStreetSpacing = 1.0;     // metres between street cameras
constexpr double kCentralRadius = 4.0;     // ring: cylinder radius of the points, metres
constexpr double kRandomBallRadius = 3.0;  // random: ball radius of the points, metres
// Street: cameras stand 1.6 +- 0.1 m high and look at a target (+-1, 9, 0.5..2.5) m away;
// facade points lie 8-10 m across the street, 0-8 m high, and at most 2 m beyond the outermost
// observer along it. A point d metres along the street from a camera is at least
// (-d + 9 * 8 - 2.5 * 1.7) / |(1, 9, 2.5)| in front of it, more than the 1 m needed while
// d < 72 - 4.25 - 9.39 = 58.36: k consecutive observers keep every point within k + 1 m.
constexpr int kMaxStreetObservers = 57;

/// A uniform integer in [0, n) (n >= 1); the rounding bias is below 2^-40 for carat's sizes.
int uniform_index(Random& random, int n) {
  return std::min(n - 1, static_cast<int>(random.uniform() * n));
}

Eigen::Vector3d gaussian3(Random& random) {
  const double x = random.normal(), y = random.normal(), z = random.normal();
  return {x, y, z};
}

/// The world-to-camera rotation of a camera at `center` looking at `target` (camera -z forward).
Eigen::Matrix3d look_at(const Eigen::Vector3d& center, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (center - target).normalized();  // backwards
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  if (up.cross(z).norm() < 0.1) up = Eigen::Vector3d::UnitX();
  const Eigen::Vector3d x = up.cross(z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R.row(0) = x.transpose();
  R.row(1) = y.transpose();
  R.row(2) = z.transpose();
  return R;
}

/// BAL parameters of a camera with rotation R (world to camera), centre and intrinsics.
BalCamera make_camera(const Eigen::Matrix3d& R, const Eigen::Vector3d& center, double focal,
                      double k1, double k2) {
  const Eigen::AngleAxisd angle_axis(R);
  const Eigen::Vector3d w = angle_axis.angle() * angle_axis.axis();
  const Eigen::Vector3d t = -R * center;
  BalCamera camera;
  camera << w, t, focal, k1, k2;
  return camera;
}

Eigen::Matrix3d rotation_of(const BalCamera& camera) {
  const Eigen::Vector3d w = camera.head<3>();
  const double angle = w.norm();
  if (angle == 0.0) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

void check_options(const BalSimulationOptions& o) {
  const auto fail = [](const std::string& what) { throw Error("simulate_bal: " + what); };
  if (o.cameras < 2) fail("cameras must be >= 2, got " + std::to_string(o.cameras));
  if (o.points < o.cameras) {
    fail("points must be >= cameras (" + std::to_string(o.cameras) +
         ") so that every camera observes one, got " + std::to_string(o.points));
  }
  if (o.observations_per_point < 2 || o.observations_per_point > o.cameras) {
    fail("observations_per_point must be in [2, cameras = " + std::to_string(o.cameras) +
         "], got " + std::to_string(o.observations_per_point));
  }
  if (o.observations_per_point > max_observations_per_point(o.layout, o.cameras)) {
    fail("observations_per_point must be at most " +
         std::to_string(max_observations_per_point(o.layout, o.cameras)) + " for the " +
         to_string(o.layout) + " layout (no facade point is in front of more consecutive " +
         "cameras), got " + std::to_string(o.observations_per_point));
  }
  if (static_cast<std::int64_t>(o.points) * o.observations_per_point >
      std::numeric_limits<int>::max()) {
    fail("points * observations_per_point must be at most 2147483647");
  }
  const auto non_negative = [&](double value, const char* name) {
    if (!std::isfinite(value) || value < 0.0) {
      fail(std::string(name) + " must be finite and >= 0, got " + message_number(value));
    }
  };
  non_negative(o.pixel_noise_sigma, "pixel_noise_sigma");
  non_negative(o.camera_rotation_sigma_rad, "camera_rotation_sigma_rad");
  non_negative(o.camera_position_sigma_m, "camera_position_sigma_m");
  non_negative(o.focal_sigma_relative, "focal_sigma_relative");
  non_negative(o.point_sigma_m, "point_sigma_m");
  if (!(o.outlier_fraction >= 0.0 && o.outlier_fraction <= 1.0)) {
    fail("outlier_fraction must be in [0, 1], got " + message_number(o.outlier_fraction));
  }
  if (!(o.outlier_pixels > 0.0) || !std::isfinite(o.outlier_pixels)) {
    fail("outlier_pixels must be finite and > 0, got " + message_number(o.outlier_pixels));
  }
  if (!(o.focal_px > 0.0) || !std::isfinite(o.focal_px)) {
    fail("focal_px must be finite and > 0, got " + message_number(o.focal_px));
  }
}

/// True cameras: rotations and centres by layout, focal lengths within 5 % of the mean and mild
/// radial distortion.
std::vector<BalCamera> true_cameras(const BalSimulationOptions& o, Random& random) {
  std::vector<BalCamera> cameras;
  cameras.reserve(static_cast<std::size_t>(o.cameras));
  for (int c = 0; c < o.cameras; ++c) {
    Eigen::Vector3d center = Eigen::Vector3d::Zero(), target = Eigen::Vector3d::Zero();
    switch (o.layout) {
      case BalLayout::kRing: {
        const double angle = 2.0 * std::numbers::pi * c / o.cameras;
        center = {kRingRadius * std::cos(angle), kRingRadius * std::sin(angle),
                  random.uniform(-0.5, 0.5)};
        target = 0.5 * Eigen::Vector3d{random.uniform(-1, 1), random.uniform(-1, 1),
                                       random.uniform(-1, 1)};
        break;
      }
      case BalLayout::kStreet: {
        center = {kStreetSpacing * c, 0.0, 1.6 + random.uniform(-0.1, 0.1)};
        target = center + Eigen::Vector3d{random.uniform(-1, 1), 9.0, random.uniform(0.5, 2.5)};
        break;
      }
      case BalLayout::kRandom: {
        const double azimuth = random.uniform(0.0, 2.0 * std::numbers::pi);
        const double elevation = std::asin(random.uniform(-0.7, 0.7));
        const double distance = random.uniform(8.0, 12.0);
        center = distance * Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                                            std::cos(elevation) * std::sin(azimuth),
                                            std::sin(elevation));
        target =
            Eigen::Vector3d{random.uniform(-1, 1), random.uniform(-1, 1), random.uniform(-1, 1)};
        break;
      }
    }
    const double focal = o.focal_px * random.uniform(0.95, 1.05);
    const double k1 = random.uniform(-0.02, 0.02);
    const double k2 = random.uniform(-0.005, 0.005);
    cameras.push_back(make_camera(look_at(center, target), center, focal, k1, k2));
  }
  return cameras;
}

/// The cameras observing point j: always camera j mod C (so every camera observes a point), then
/// neighbours along the ring or street, or random others.
void choose_cameras(const BalSimulationOptions& o, int j, Random& random, std::vector<int>* out) {
  const int C = o.cameras, k = o.observations_per_point;
  const int anchor = j % C;
  out->clear();
  switch (o.layout) {
    case BalLayout::kRing: {  // k cameras `stride` apart, spanning about a quarter of the ring
      const int stride = std::max(1, C / (4 * (k - 1)));
      const int start = anchor - uniform_index(random, k) * stride;
      for (int i = 0; i < k; ++i) out->push_back(((start + i * stride) % C + C) % C);
      break;
    }
    case BalLayout::kStreet: {  // k consecutive cameras
      const int start = std::clamp(anchor - uniform_index(random, k), 0, C - k);
      for (int i = 0; i < k; ++i) out->push_back(start + i);
      break;
    }
    case BalLayout::kRandom: {
      out->push_back(anchor);
      while (static_cast<int>(out->size()) < k) {
        const int c = uniform_index(random, C);
        if (std::find(out->begin(), out->end(), c) == out->end()) out->push_back(c);
      }
      break;
    }
  }
}

/// A point that the cameras `observers` see, by layout.
Eigen::Vector3d sample_point(const BalSimulationOptions& o, const std::vector<int>& observers,
                             Random& random) {
  switch (o.layout) {
    case BalLayout::kRing: {
      const double radius = kCentralRadius * std::sqrt(random.uniform());
      const double angle = random.uniform(0.0, 2.0 * std::numbers::pi);
      return {radius * std::cos(angle), radius * std::sin(angle), random.uniform(-2.0, 2.0)};
    }
    case BalLayout::kStreet: {
      const auto [lo, hi] = std::minmax_element(observers.begin(), observers.end());
      const double x = random.uniform(kStreetSpacing * *lo - 2.0, kStreetSpacing * *hi + 2.0);
      return {x, random.uniform(8.0, 10.0), random.uniform(0.0, 8.0)};
    }
    case BalLayout::kRandom:
    default: {
      Eigen::Vector3d p;
      do {
        p = Eigen::Vector3d{random.uniform(-1, 1), random.uniform(-1, 1), random.uniform(-1, 1)};
      } while (p.squaredNorm() > 1.0);
      return kRandomBallRadius * p;
    }
  }
}

/// Whether every observer has the point at least 1 m in front of it.
bool seen_by_all(const std::vector<BalCamera>& cameras, const std::vector<int>& observers,
                 const Eigen::Vector3d& point) {
  for (int c : observers) {
    double P[3];
    snavely_camera_point(cameras[static_cast<std::size_t>(c)].data(), point.data(), P);
    if (!(P[2] < -1.0)) return false;
  }
  return true;
}

}  // namespace

const char* to_string(BalLayout layout) {
  switch (layout) {
    case BalLayout::kRing:
      return "ring";
    case BalLayout::kStreet:
      return "street";
    case BalLayout::kRandom:
      return "random";
  }
  return "unknown";
}

BalLayout parse_bal_layout(std::string_view name) {
  for (BalLayout layout : {BalLayout::kRing, BalLayout::kStreet, BalLayout::kRandom}) {
    if (name == to_string(layout)) return layout;
  }
  throw Error("unknown BAL layout " + quote_bytes(name) + " (valid: ring, street, random)");
}

int max_observations_per_point(BalLayout layout, int cameras) {
  return layout == BalLayout::kStreet ? std::min(cameras, kMaxStreetObservers) : cameras;
}

BalScene simulate_bal(const BalSimulationOptions& o) {
  check_options(o);
  Random random(o.seed);
  BalScene scene;
  BalProblem& truth = scene.truth;
  truth.cameras = true_cameras(o, random);

  const std::size_t num_observations =
      static_cast<std::size_t>(o.points) * static_cast<std::size_t>(o.observations_per_point);
  truth.points.reserve(static_cast<std::size_t>(o.points));
  truth.observations.reserve(num_observations);
  std::vector<int> observers;
  for (int j = 0; j < o.points; ++j) {
    choose_cameras(o, j, random, &observers);
    Eigen::Vector3d point = sample_point(o, observers, random);
    for (int attempt = 0; !seen_by_all(truth.cameras, observers, point); ++attempt) {
      if (attempt == 1000) {
        throw Error("simulate_bal: found no place for point " + std::to_string(j) +
                    " in front of all its cameras");
      }
      point = sample_point(o, observers, random);
    }
    truth.points.push_back(point);
    for (int c : observers) {
      double image[2];
      snavely_project(truth.cameras[static_cast<std::size_t>(c)].data(), point.data(), image);
      truth.observations.push_back({c, j, image[0], image[1]});
    }
  }

  // Observations: noise on every one, then exactly round(fraction * N) outliers chosen by
  // selection sampling (each subset of that size equally likely).
  BalProblem& problem = scene.problem;
  problem.observations = truth.observations;
  for (BalObservation& obs : problem.observations) {
    obs.x += o.pixel_noise_sigma * random.normal();
    obs.y += o.pixel_noise_sigma * random.normal();
  }
  scene.outlier.assign(num_observations, 0);
  std::size_t wanted = static_cast<std::size_t>(
      std::llround(o.outlier_fraction * static_cast<double>(num_observations)));
  for (std::size_t k = 0; k < num_observations && wanted > 0; ++k) {
    if (random.uniform() * static_cast<double>(num_observations - k) <
        static_cast<double>(wanted)) {
      scene.outlier[k] = 1;
      --wanted;
      const double angle = random.uniform(0.0, 2.0 * std::numbers::pi);
      const double distance = o.outlier_pixels * random.uniform(0.5, 1.0);
      problem.observations[k].x += distance * std::cos(angle);
      problem.observations[k].y += distance * std::sin(angle);
    }
  }

  // The start: cameras rotated, moved and refocused, points moved.
  problem.cameras.reserve(truth.cameras.size());
  for (const BalCamera& camera : truth.cameras) {
    const Eigen::Matrix3d R = rotation_of(camera);
    const Eigen::Vector3d center = -R.transpose() * camera.segment<3>(3);
    const Eigen::Vector3d delta = o.camera_rotation_sigma_rad * gaussian3(random);
    Eigen::Matrix3d R_start = R;
    if (delta.norm() > 0.0) R_start = Eigen::AngleAxisd(delta.norm(), delta.normalized()) * R;
    const Eigen::Vector3d center_start = center + o.camera_position_sigma_m * gaussian3(random);
    const double focal = camera[6] * (1.0 + o.focal_sigma_relative * random.normal());
    problem.cameras.push_back(make_camera(R_start, center_start, focal, camera[7], camera[8]));
  }
  problem.points.reserve(truth.points.size());
  for (const Eigen::Vector3d& point : truth.points) {
    problem.points.push_back(point + o.point_sigma_m * gaussian3(random));
  }
  return scene;
}

}  // namespace carat
