// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/matching/matching.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <map>
#include <mutex>
#include <opencv2/calib3d.hpp>
#include <memory>
#include <opencv2/flann.hpp>
#include <opencv2/flann/random.h>
#include <set>
#include <thread>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/base/parallel.h"

namespace aerotri {

void MatchOptions::Check() const {
  CheckOption(ratio > 0.0 && ratio <= 1.0, "matching ratio", ratio, "Lowe's ratio in (0, 1]");
  CheckOption(min_inliers >= 8, "matching min_inliers", min_inliers, "at least 8 (two-view geometry needs them)");
  CheckOption(max_epipolar_px > 0.0 && std::isfinite(max_epipolar_px), "matching max_epipolar_px", max_epipolar_px,
              "a positive number of pixels");
  CheckOption(gps_neighbours >= 1, "--gps-neighbours", gps_neighbours, "at least 1 image");
  CheckOption(exhaustive_up_to >= 0, "matching exhaustive_up_to", exhaustive_up_to, "0 or more images");
  CheckOption(flann_checks >= 1, "matching flann_checks", flann_checks, "at least 1");
  CheckOption(num_threads >= 0, "--threads", num_threads, "0 (all cores) or more");
}

std::vector<std::pair<int, int>> SelectPairs(const std::vector<std::optional<Eigen::Vector2d>>& gps,
                                             const MatchOptions& options, std::string* strategy) {
  const int n = static_cast<int>(gps.size());
  std::set<std::pair<int, int>> pairs;
  const bool all_gps = std::all_of(gps.begin(), gps.end(), [](const auto& g) { return g.has_value(); });
  if (n <= options.exhaustive_up_to || !all_gps) {
    for (int i = 0; i < n; ++i) {
      for (int j = i + 1; j < n; ++j) pairs.insert({i, j});
    }
    if (strategy) {
      *strategy = !all_gps ? "exhaustive (not every image has GPS)"
                           : "exhaustive (" + std::to_string(n) + " images)";
    }
  } else {
    for (int i = 0; i < n; ++i) {
      std::vector<std::pair<double, int>> d;
      for (int j = 0; j < n; ++j) {
        if (j != i) d.push_back({(*gps[i] - *gps[j]).norm(), j});
      }
      std::sort(d.begin(), d.end());
      for (int k = 0; k < std::min<int>(options.gps_neighbours, static_cast<int>(d.size())); ++k) {
        const int j = d[k].second;
        pairs.insert({std::min(i, j), std::max(i, j)});
      }
    }
    if (strategy) {
      *strategy = "GPS neighbourhoods (" + std::to_string(options.gps_neighbours) +
                  " nearest per image)";
    }
  }
  return {pairs.begin(), pairs.end()};
}

namespace {

// The state OpenCV's RNG is reset to before each RANSAC (a fixed seed:
// runs are reproducible whatever the thread schedule).
constexpr std::uint64_t kRansacSeed = 0x2545F4914F6CDD1DULL;

PairMatches MatchOne(const ImageFeatures& a, const cv::Mat& a_desc, const ImageFeatures& b,
                     cv::flann::Index& b_index, int i, int j, const MatchOptions& options) {
  PairMatches result;
  result.i = i;
  result.j = j;
  if (a.keypoints.size() < 8 || b.keypoints.size() < 8) return result;
  cv::Mat idx, dist;
  b_index.knnSearch(a_desc, idx, dist, 2, cv::flann::SearchParams(options.flann_checks));
  // Ratio test, then one-to-one: keep the closest query for each train feature.
  std::map<int, std::pair<float, int>> best;  // train -> (distance, query)
  const float ratio2 = static_cast<float>(options.ratio * options.ratio);
  for (int q = 0; q < idx.rows; ++q) {
    const int t0 = idx.at<int>(q, 0);
    const float d0 = dist.at<float>(q, 0), d1 = dist.at<float>(q, 1);
    if (t0 < 0 || !(d0 < ratio2 * d1)) continue;
    auto it = best.find(t0);
    if (it == best.end() || d0 < it->second.first) best[t0] = {d0, q};
  }
  std::vector<cv::Point2f> pa, pb;
  std::vector<std::array<int, 2>> putative;
  for (const auto& [t, dq] : best) {
    putative.push_back({dq.second, t});
    pa.emplace_back(a.keypoints[dq.second].x, a.keypoints[dq.second].y);
    pb.emplace_back(b.keypoints[t].x, b.keypoints[t].y);
  }
  result.putative = static_cast<int>(putative.size());
  if (result.putative < options.min_inliers) return result;
  std::vector<std::uint8_t> mask;
  const cv::Mat f = cv::findFundamentalMat(pa, pb, cv::USAC_MAGSAC, options.max_epipolar_px, 0.999,
                                           10000, mask);
  if (f.empty() || mask.size() != putative.size()) return result;
  for (size_t k = 0; k < putative.size(); ++k) {
    if (mask[k]) result.inliers.push_back(putative[k]);
  }
  if (static_cast<int>(result.inliers.size()) < options.min_inliers) {
    result.inliers.clear();
    return result;
  }
  std::vector<cv::Point2f> ia, ib;
  for (const auto& m : result.inliers) {
    ia.emplace_back(a.keypoints[m[0]].x, a.keypoints[m[0]].y);
    ib.emplace_back(b.keypoints[m[1]].x, b.keypoints[m[1]].y);
  }
  std::vector<std::uint8_t> hmask;
  // OpenCV's RANSAC draws from its thread-local RNG, whose state would
  // depend on which pairs this thread verified before: reseeded, a pair's
  // result depends on the pair alone, however the threads are scheduled.
  cv::theRNG().state = kRansacSeed;
  const cv::Mat h = cv::findHomography(ia, ib, cv::RANSAC, 2.0 * options.max_epipolar_px, hmask, 2000);
  if (!h.empty()) result.homography_inliers = static_cast<int>(std::count(hmask.begin(), hmask.end(), 1));
  return result;
}

}  // namespace

std::vector<PairMatches> MatchPairs(const std::vector<ImageFeatures>& features,
                                    const std::vector<std::pair<int, int>>& pairs,
                                    const MatchOptions& options, const ProgressCallback& progress) {
  // One task per train image j, so that each FLANN index is built once and
  // used by one thread only.
  std::map<int, std::vector<int>> queries_of;
  for (const auto& [i, j] : pairs) queries_of[j].push_back(i);
  std::vector<std::pair<int, std::vector<int>>> tasks(queries_of.begin(), queries_of.end());
  std::vector<cv::Mat> float_desc(features.size());
  for (size_t k = 0; k < features.size(); ++k) float_desc[k] = features[k].FloatDescriptors();

  std::vector<PairMatches> verified;
  std::mutex mutex, flann_build;
  std::atomic<size_t> done_pairs{0};
  const size_t total = pairs.size();
  ParallelFor(tasks.size(), ThreadCount(options.num_threads), [&](size_t t) {
    const int j = tasks[t].first;
    if (features[j].keypoints.size() < 8) {
      done_pairs += tasks[t].second.size();
      return;
    }
    // FLANN's randomised trees draw from the C library's rand(): build each
    // under a lock with a seed of its own, so matches do not depend on
    // thread scheduling and a re-run gives the same survey.
    std::unique_ptr<cv::flann::Index> built;
    {
      std::lock_guard<std::mutex> lock(flann_build);
      cvflann::seed_random(1000u + static_cast<unsigned>(j));
      built = std::make_unique<cv::flann::Index>(float_desc[j], cv::flann::KDTreeIndexParams(4));
    }
    cv::flann::Index& index = *built;
    for (int i : tasks[t].second) {
      PairMatches m = MatchOne(features[i], float_desc[i], features[j], index, i, j, options);
      const size_t done = ++done_pairs;
      std::lock_guard<std::mutex> lock(mutex);
      if (!m.inliers.empty()) verified.push_back(std::move(m));
      if (progress && (done % 10 == 0 || done == total)) {
        progress(static_cast<double>(done) / std::max<size_t>(1, total),
                 std::to_string(done) + "/" + std::to_string(total) + " pairs, " + std::to_string(verified.size()) +
                     " verified");
      }
    }
  });
  std::sort(verified.begin(), verified.end(), [](const PairMatches& a, const PairMatches& b) {
    return std::make_pair(a.i, a.j) < std::make_pair(b.i, b.j);
  });
  return verified;
}

void WriteMatches(const std::vector<PairMatches>& matches, const std::filesystem::path& path) {
  WriteFileAtomically(path, [&](std::ostream& out) {
    out.write("AERMTCH1", 8);
    const std::int32_t n = static_cast<std::int32_t>(matches.size());
    out.write(reinterpret_cast<const char*>(&n), 4);
    for (const PairMatches& m : matches) {
      const std::int32_t head[5] = {m.i, m.j, m.putative, m.homography_inliers,
                                    static_cast<std::int32_t>(m.inliers.size())};
      out.write(reinterpret_cast<const char*>(head), sizeof(head));
      for (const auto& in : m.inliers) {
        const std::int32_t v[2] = {in[0], in[1]};
        out.write(reinterpret_cast<const char*>(v), 8);
      }
    }
  });
}

std::vector<PairMatches> ReadMatches(const std::filesystem::path& path) {
  const std::string data = ReadTextFile(path);
  const std::string p = path.string();
  if (data.size() < 12 || std::memcmp(data.data(), "AERMTCH1", 8) != 0) {
    throw ParseError(p, 0, "not an aerotri match file (bad magic)");
  }
  std::int32_t n;
  std::memcpy(&n, data.data() + 8, 4);
  size_t off = 12;
  std::vector<PairMatches> out;
  for (std::int32_t k = 0; k < n; ++k) {
    if (off + 20 > data.size()) throw ParseError(p, 0, "truncated match file");
    std::int32_t head[5];
    std::memcpy(head, data.data() + off, 20);
    off += 20;
    if (head[4] < 0 || off + static_cast<size_t>(head[4]) * 8 > data.size()) {
      throw ParseError(p, 0, "truncated match file");
    }
    PairMatches m;
    m.i = head[0];
    m.j = head[1];
    m.putative = head[2];
    m.homography_inliers = head[3];
    m.inliers.resize(head[4]);
    for (auto& in : m.inliers) {
      std::int32_t v[2];
      std::memcpy(v, data.data() + off, 8);
      off += 8;
      in = {v[0], v[1]};
    }
    out.push_back(std::move(m));
  }
  return out;
}

void ValidateMatches(const std::vector<PairMatches>& matches, const std::vector<ImageFeatures>& features,
                     const std::filesystem::path& path) {
  const int n = static_cast<int>(features.size());
  const std::string fix = ": the file does not belong to these features (stale after a features rerun, or "
                          "corrupt); rerun the match stage (aerotri match --force)";
  for (size_t k = 0; k < matches.size(); ++k) {
    const PairMatches& m = matches[k];
    if (m.i < 0 || m.i >= n || m.j < 0 || m.j >= n || m.i == m.j) {
      throw ParseError(path.string(), 0,
                       "pair " + std::to_string(k) + " joins images " + std::to_string(m.i) + " and " +
                           std::to_string(m.j) + ", expected two different indices in [0, " +
                           std::to_string(n) + ")" + fix);
    }
    const int ni = static_cast<int>(features[m.i].keypoints.size());
    const int nj = static_cast<int>(features[m.j].keypoints.size());
    for (const auto& in : m.inliers) {
      if (in[0] < 0 || in[0] >= ni || in[1] < 0 || in[1] >= nj) {
        throw ParseError(path.string(), 0,
                         "pair " + std::to_string(k) + " (images " + std::to_string(m.i) + ", " +
                             std::to_string(m.j) + ") refers to features " + std::to_string(in[0]) + " and " +
                             std::to_string(in[1]) + " but the images have " + std::to_string(ni) + " and " +
                             std::to_string(nj) + fix);
      }
    }
  }
}

}  // namespace aerotri
