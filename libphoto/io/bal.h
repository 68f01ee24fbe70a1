// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// "Bundle Adjustment in the Large" problems (Agarwal, Snavely, Seitz,
// Szeliski, ECCV 2010), plain text or bzip2.
//
// Format: `num_cameras num_points num_observations`; then per observation
// `camera_index point_index x y`; then 9 numbers per camera (Rodrigues
// rotation, translation, f, k1, k2); then 3 per point. BAL's camera looks down
// -z with y up and measures pixels from the image centre: P = R X + t,
// p = -P / P.z. On reading, each camera becomes an image with its own
// SNAVELY camera group and the frame is converted to aerotri's (+z forward,
// y down): R_aerotri = diag(1, -1, -1) R_bal, y_aerotri = -y_bal. Residual
// magnitudes, and so costs, are unchanged; writing converts back.
//
// Errors: ParseError with the line number for a malformed, truncated or
// inconsistent file (index out of range, non-finite value).

#include <filesystem>

#include "libphoto/model/sparse_model.h"

namespace aerotri {

SparseModel ReadBalProblem(const std::filesystem::path& path);

// Writes model (as read by ReadBalProblem and possibly adjusted) back in BAL
// text, atomically.
void WriteBalProblem(const SparseModel& model, const std::filesystem::path& path);

}  // namespace aerotri
