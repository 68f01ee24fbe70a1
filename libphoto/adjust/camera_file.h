// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Interior orientation from a calibration certificate: a small text file of
// `name value [sigma S | fixed]` lines, '#' comments, one camera:
//
//   units mm              px (default) or mm
//   pixel_size_mm 0.006   required with mm
//   width 11310           image size in pixels: needed to adjust from
//   height 17310            measurements alone (no model to take it from);
//                           with a model, checked against it
//   f 120.0 sigma 0.002   camera constant (mm) or focal length (px)
//   x0 0.011 sigma 0.002  mm: principal point offset from the image centre,
//   y0 -0.005 fixed         x right, y up (the fiducial convention)
//   cx 5654.5             px: principal point, aerotri's pixel convention
//   cy 8654.5               (the centre of the top-left pixel is 0, 0)
//   k1 -1.2e-2 sigma 1e-3 Brown radial and tangential coefficients as
//   k2 ... k3 ... p1 ... p2 ...   OpenCV defines them (dimensionless, on
//                                 normalised image coordinates) in both units
//
// Without `sigma` or `fixed` a value is a start only, refined freely;
// `sigma S` is a prior (S in the line's unit); `fixed` holds it. Errors
// name the file, the line and what was expected.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/model/sparse_model.h"

namespace aerotri {

struct CameraFileValue {
  std::string name;  // as written: f, x0, y0, cx, cy, k1, k2, k3, p1, p2
  double value = 0.0;
  std::optional<double> sigma;
  bool fixed = false;
  int line = 0;
};

struct CameraFile {
  std::string path;
  bool millimetres = false;
  double pixel_size_mm = 0.0;
  int width = 0;   // px; 0: not given
  int height = 0;
  int size_line = 0;  // the line of width / height, for errors
  std::vector<CameraFileValue> values;

  // The camera the certificate describes, on its own (no model): the Brown
  // model at width x height with the file's values (held or prior values
  // as starts). Throws InvalidArgument naming the file when it lacks
  // width, height or f.
  Camera ToCamera() const;
};

CameraFile ReadCameraFile(const std::filesystem::path& path);

// Sets every camera group's parameters to the file's (in pixels), and adds
// the file's priors and held parameters to *options. The certificate is in
// full-resolution pixels; full_from_working[c] (default 1) is camera c's
// full / working size ratio, when the model is at a reduced resolution.
// Throws InvalidArgument naming the file and line when a parameter is not
// in a camera's model, or when the file's width / height are not the
// camera's full-resolution size.
void ApplyCameraFile(const CameraFile& file, SparseModel* model, BundleOptions* options,
                     const std::vector<double>& full_from_working = {});

}  // namespace aerotri
