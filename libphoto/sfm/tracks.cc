// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/sfm/tracks.h"

#include <numeric>
#include <unordered_map>

namespace aerotri {
namespace {

struct UnionFind {
  std::vector<int> parent;
  explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int Find(int x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  }
  void Union(int a, int b) {
    a = Find(a);
    b = Find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
};

}  // namespace

Tracks BuildTracks(const std::vector<int>& features_per_image, const std::vector<PairMatches>& matches) {
  std::vector<int> offset(features_per_image.size() + 1, 0);
  for (size_t i = 0; i < features_per_image.size(); ++i) offset[i + 1] = offset[i] + features_per_image[i];
  UnionFind uf(offset.back());
  std::vector<char> used(offset.back(), 0);
  for (const PairMatches& m : matches) {
    for (const auto& in : m.inliers) {
      const int a = offset[m.i] + in[0], b = offset[m.j] + in[1];
      uf.Union(a, b);
      used[a] = used[b] = 1;
    }
  }
  std::unordered_map<int, int> track_of_root;
  std::vector<std::vector<TrackElement>> raw;
  for (size_t image = 0; image < features_per_image.size(); ++image) {
    for (int f = 0; f < features_per_image[image]; ++f) {
      const int node = offset[image] + f;
      if (!used[node]) continue;
      const int root = uf.Find(node);
      auto [it, inserted] = track_of_root.emplace(root, static_cast<int>(raw.size()));
      if (inserted) raw.emplace_back();
      raw[it->second].push_back({static_cast<int>(image), f});
    }
  }
  Tracks out;
  out.track_of.resize(features_per_image.size());
  for (size_t i = 0; i < features_per_image.size(); ++i) out.track_of[i].assign(features_per_image[i], -1);
  for (auto& track : raw) {
    bool consistent = track.size() >= 2;
    for (size_t a = 1; a < track.size() && consistent; ++a) {
      // Elements are in image order: a repeated image is adjacent.
      if (track[a].image == track[a - 1].image) consistent = false;
    }
    if (!consistent) {
      if (track.size() >= 2) ++out.dropped_inconsistent;
      continue;
    }
    const int id = static_cast<int>(out.tracks.size());
    for (const TrackElement& e : track) out.track_of[e.image][e.feature] = id;
    out.tracks.push_back(std::move(track));
  }
  return out;
}

}  // namespace aerotri
