// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// marks.html: the review page of ground control marked from coordinates
// (libphoto/targets/marking.h), one self-contained HTML file (no network:
// the image chips are inline JPEGs, the script and styles inline).
//
// Per point: its status and reason, and a chip of every photo it was
// predicted in (the predicted place as a blue cross, the mark as a red
// circle), with the detection's confidence, its reprojection error and,
// once the survey is adjusted, the mark's residual and w-test (a mark the
// adjustment rejected starts rejected and says so). The user drags a mark
// (or clicks to place one where none was found; arrow keys nudge it by
// 0.1 px, with Shift 1 px), accepts or rejects it, rejects a whole point,
// and downloads the corrected gcp_list.txt and check list, in the format
// WriteGcpFile writes (pixels: (0, 0) at the centre of the top-left pixel).
//
// Chip geometry: a chip is chip_size x chip_size photo pixels whose
// top-left pixel is (ox, oy), drawn at scale CSS pixels per photo pixel;
// the photo point (x, y) is at CSS ((x - ox + 0.5) * scale, (y - oy + 0.5)
// * scale) within it. Parts of a chip outside the photo are grey.

#include <functional>
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>


namespace aerotri {

struct ReviewPageInput {
  // marks.json: per point its coordinates' fields (GcpCoordinatesText,
  // GcpSigmasText) and per photo the prediction and the mark; per role
  // ("files": control, check) the coordinate list's CRS line.
  nlohmann::json marking;
  // report.json's adjustment.data_snooping.marks (point, image, residual_px,
  // w, rejected) once the survey is adjusted; null before.
  nlohmann::json adjustment_marks;
  std::string title;  // the survey (workspace) name
};

struct ReviewPageOptions {
  int chip_size = 96;  // photo pixels
  int scale = 3;       // CSS pixels per photo pixel
  int jpeg_quality = 92;
};

// load_image: the photo by name, full resolution, 8-bit BGR or grey, as it
// was marked (EXIF orientation ignored); an empty Mat draws a grey chip.
std::string RenderReviewPage(const ReviewPageInput& input, const std::function<cv::Mat(const std::string&)>& load_image,
                             const ReviewPageOptions& options = {});

}  // namespace aerotri
