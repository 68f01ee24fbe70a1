// SPDX-License-Identifier: BSD-3-Clause
// Calibration certificates (--camera-file).
#include "libphoto/adjust/camera_file.h"
#include "tests/fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = aerotri::fuzz::WriteInput("camera.txt", data, size);
  aerotri::fuzz::ExpectOnlyCleanErrors([&] { aerotri::ReadCameraFile(path); });
  return 0;
}
