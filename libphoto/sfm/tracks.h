// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Feature tracks: connected components of verified matches over (image,
// feature) nodes (union-find). A track that holds two features of one image
// is inconsistent (a wrong match somewhere) and is dropped whole.

#include <vector>

#include "libphoto/matching/matching.h"

namespace aerotri {

struct TrackElement {
  int image = 0;
  int feature = 0;
};

struct Tracks {
  std::vector<std::vector<TrackElement>> tracks;
  // track_of[image][feature]: track index or -1.
  std::vector<std::vector<int>> track_of;
  int dropped_inconsistent = 0;
};

Tracks BuildTracks(const std::vector<int>& features_per_image,
                   const std::vector<PairMatches>& matches);

}  // namespace aerotri
