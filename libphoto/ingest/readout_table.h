// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Rolling-shutter readout times of known cameras, for photos that state
// their motion but not their readout (DJI's flight speeds). Each entry
// names where its figure comes from; a camera not in the table has no
// readout here (global shutter, or --rolling-shutter estimate).

#include <optional>
#include <string>

namespace aerotri {

struct KnownReadout {
  double readout_time_s = 0.0;  // first row to last
  std::string camera;           // "DJI FC6310" as the table names it
  std::string source;           // where the figure was measured or published
};

// The readout of the camera `make` `model` (EXIF Make and Model, matched
// without regard to case or surrounding spaces) at `megapixels` of capture
// (a sensor read in a cropped or binned mode reads out faster); nullopt
// when the table does not know the camera.
std::optional<KnownReadout> KnownCameraReadout(const std::string& make, const std::string& model,
                                               double megapixels);

}  // namespace aerotri
