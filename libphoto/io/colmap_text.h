// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// COLMAP text models: cameras.txt, images.txt, points3D.txt (COLMAP's
// "Output format" documentation), so that a model made elsewhere can be
// georeferenced by aerotri, and aerotri's models opened in COLMAP.
//
// Poses: COLMAP stores cam_from_world as a quaternion (QW QX QY QZ) and a
// translation, x_cam = R X + t, with the same camera frame as aerotri.
// Pixels: COLMAP puts the centre of the top-left pixel at (0.5, 0.5); aerotri
// at (0, 0). Observations and principal points are shifted by 0.5 at the
// boundary.
// Camera models on reading: SIMPLE_PINHOLE -> PINHOLE; PINHOLE (fx, fy) ->
// PINHOLE with f = (fx + fy) / 2 when they agree within 0.1 %; SIMPLE_RADIAL,
// RADIAL, OPENCV, FULL_OPENCV (k4..k6 = 0) -> BROWN. Other models, or
// unequal focal lengths, are refused with the file and line. On writing:
// PINHOLE -> SIMPLE_PINHOLE, BROWN -> FULL_OPENCV, SNAVELY -> RADIAL, all
// exact. 2D points without a 3D point are not kept.
//
// Rolling shutters: aerotri adds rolling_shutter.txt beside the three files
// when any photo is a rolling shutter's, one line per such photo:
// IMAGE_ID READOUT_TIME_S VX VY VZ NAME, the readout from the first row to
// the last and the camera's velocity in the model's frame (m/s), as
// RollingShutterMotion holds them. COLMAP ignores the file; without it every
// photo is a global shutter's. So whatever reads a model sees each row from
// where its camera was, with the motion that the model was adjusted with.

#include <filesystem>

#include "libphoto/model/sparse_model.h"

namespace aerotri {

SparseModel ReadColmapText(const std::filesystem::path& dir);

// Writes the three files into dir (created if needed), each atomically, and
// rolling_shutter.txt where a photo has one (a stale one is removed).
// Check points and control points are written as ordinary 3D points.
void WriteColmapText(const SparseModel& model, const std::filesystem::path& dir);

}  // namespace aerotri
