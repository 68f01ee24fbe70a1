// SPDX-License-Identifier: BSD-3-Clause
// The reference for bench/bal_bench.sh: a BAL problem solved through Ceres'
// public API configured as Ceres 2.1's examples/bundle_adjuster configures
// it (Debian ships the headers and library but not the example's source, so
// this small runner stands in for it; written here, not copied).
//
// As the example: the problem is read from plain text with fscanf, then
// normalised (points centred on their median, scaled so that their median
// absolute deviation is 100; cameras moved with them), one autodiff
// residual per observation (Snavely model: angle-axis, translation, f, k1,
// k2; P = R X + t, p = -P / P.z, pixel = f (1 + k1 r² + k2 r⁴) p), no loss,
// Levenberg–Marquardt with the linear solver given, the points eliminated
// first (user ordering), the given number of threads.
//
// "Stopped at the same cost": with --target-cost C the solve ends at the
// first iteration whose cost is at most C (an oracle no real solver has).
//
// Usage: ceres_bal_reference PROBLEM.txt [--solver dense_schur|sparse_schur|iterative_schur]
//        [--threads N] [--max-iterations N] [--target-cost C]
// Prints one line on stdout:
//   initial_cost=… final_cost=… iterations=… solve_s=… time_s=…
#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <glog/logging.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

struct Problem {
  int num_cameras = 0, num_points = 0, num_observations = 0;
  std::vector<int> camera_index, point_index;
  std::vector<double> observations;  // 2 per observation
  std::vector<double> cameras;       // 9 per camera
  std::vector<double> points;        // 3 per point
};

bool Read(const char* path, Problem* p) {
  FILE* f = std::fopen(path, "r");
  if (f == nullptr) return false;
  bool ok = std::fscanf(f, "%d %d %d", &p->num_cameras, &p->num_points, &p->num_observations) == 3;
  p->camera_index.resize(p->num_observations);
  p->point_index.resize(p->num_observations);
  p->observations.resize(2 * static_cast<size_t>(p->num_observations));
  for (int i = 0; ok && i < p->num_observations; ++i) {
    ok = std::fscanf(f, "%d %d %lf %lf", &p->camera_index[i], &p->point_index[i],
                     &p->observations[2 * i], &p->observations[2 * i + 1]) == 4;
  }
  p->cameras.resize(9 * static_cast<size_t>(p->num_cameras));
  p->points.resize(3 * static_cast<size_t>(p->num_points));
  for (double& v : p->cameras) ok = ok && std::fscanf(f, "%lf", &v) == 1;
  for (double& v : p->points) ok = ok && std::fscanf(f, "%lf", &v) == 1;
  std::fclose(f);
  return ok;
}

double Median(std::vector<double> v) {
  auto mid = v.begin() + v.size() / 2;
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// Centre the points on their per-axis median and scale them so that their
// median absolute deviation is 100; move the cameras with them.
void Normalize(Problem* p) {
  double median[3];
  std::vector<double> axis(p->num_points);
  for (int k = 0; k < 3; ++k) {
    for (int i = 0; i < p->num_points; ++i) axis[i] = p->points[3 * i + k];
    median[k] = Median(axis);
  }
  std::vector<double> deviation(p->num_points);
  for (int i = 0; i < p->num_points; ++i) {
    double d = 0.0;
    for (int k = 0; k < 3; ++k) d += std::abs(p->points[3 * i + k] - median[k]);
    deviation[i] = d;
  }
  const double scale = 100.0 / Median(deviation);
  for (int i = 0; i < p->num_points; ++i) {
    for (int k = 0; k < 3; ++k) p->points[3 * i + k] = scale * (p->points[3 * i + k] - median[k]);
  }
  for (int c = 0; c < p->num_cameras; ++c) {
    double* cam = &p->cameras[9 * c];
    // Centre C = -Rᵀ t; moved as the points, then t = -R C again.
    double minus_aa[3] = {-cam[0], -cam[1], -cam[2]};
    double centre[3];
    ceres::AngleAxisRotatePoint(minus_aa, cam + 3, centre);
    for (int k = 0; k < 3; ++k) centre[k] = scale * (-centre[k] - median[k]);
    double rotated[3];
    ceres::AngleAxisRotatePoint(cam, centre, rotated);
    for (int k = 0; k < 3; ++k) cam[3 + k] = -rotated[k];
  }
}

struct SnavelyResidual {
  SnavelyResidual(double x, double y) : x(x), y(y) {}
  template <typename T>
  bool operator()(const T* camera, const T* point, T* residual) const {
    T p[3];
    ceres::AngleAxisRotatePoint(camera, point, p);
    for (int k = 0; k < 3; ++k) p[k] += camera[3 + k];
    const T xp = -p[0] / p[2];
    const T yp = -p[1] / p[2];
    const T r2 = xp * xp + yp * yp;
    const T distortion = T(1.0) + r2 * (camera[7] + camera[8] * r2);
    residual[0] = camera[6] * distortion * xp - T(x);
    residual[1] = camera[6] * distortion * yp - T(y);
    return true;
  }
  double x, y;
};

class StopAtCost final : public ceres::IterationCallback {
 public:
  explicit StopAtCost(double target) : target_(target) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    return s.cost <= target_ ? ceres::SOLVER_TERMINATE_SUCCESSFULLY : ceres::SOLVER_CONTINUE;
  }

 private:
  double target_;
};

int Usage() {
  std::fprintf(stderr,
               "usage: ceres_bal_reference PROBLEM.txt [--solver dense_schur|sparse_schur|iterative_schur] "
               "[--threads N] [--max-iterations N] [--target-cost C]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  const auto start = Clock::now();
  google::InitGoogleLogging(argv[0]);
  if (argc < 2) return Usage();
  std::string solver = "dense_schur";
  int threads = 2, max_iterations = 50;
  double target = 0.0;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) return Usage();
    if (a == "--solver") solver = argv[++i];
    else if (a == "--threads") threads = std::atoi(argv[++i]);
    else if (a == "--max-iterations") max_iterations = std::atoi(argv[++i]);
    else if (a == "--target-cost") target = std::atof(argv[++i]);
    else return Usage();
  }
  Problem bal;
  if (!Read(argv[1], &bal)) {
    std::fprintf(stderr, "ceres_bal_reference: cannot read %s as a plain-text BAL problem\n", argv[1]);
    return 1;
  }
  Normalize(&bal);

  ceres::Problem problem;
  for (int i = 0; i < bal.num_observations; ++i) {
    auto* cost = new ceres::AutoDiffCostFunction<SnavelyResidual, 2, 9, 3>(
        new SnavelyResidual(bal.observations[2 * i], bal.observations[2 * i + 1]));
    problem.AddResidualBlock(cost, nullptr, &bal.cameras[9 * bal.camera_index[i]],
                             &bal.points[3 * bal.point_index[i]]);
  }
  ceres::Solver::Options options;
  options.minimizer_type = ceres::TRUST_REGION;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  if (solver == "dense_schur") options.linear_solver_type = ceres::DENSE_SCHUR;
  else if (solver == "sparse_schur") options.linear_solver_type = ceres::SPARSE_SCHUR;
  else if (solver == "iterative_schur") options.linear_solver_type = ceres::ITERATIVE_SCHUR;
  else return Usage();
  options.preconditioner_type = ceres::JACOBI;
  options.num_threads = threads;
  options.max_num_iterations = max_iterations;
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (int i = 0; i < bal.num_points; ++i) ordering->AddElementToGroup(&bal.points[3 * i], 0);
  for (int c = 0; c < bal.num_cameras; ++c) ordering->AddElementToGroup(&bal.cameras[9 * c], 1);
  options.linear_solver_ordering = ordering;
  StopAtCost stop(target);
  if (target > 0.0) {
    options.callbacks.push_back(&stop);
    options.update_state_every_iteration = false;
  }
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  const double total = std::chrono::duration<double>(Clock::now() - start).count();
  std::printf("initial_cost=%.6e final_cost=%.6e iterations=%d solve_s=%.3f time_s=%.3f\n", summary.initial_cost,
              summary.final_cost, static_cast<int>(summary.iterations.size()) - 1, summary.total_time_in_seconds,
              total);
  return summary.IsSolutionUsable() ? 0 : 1;
}
