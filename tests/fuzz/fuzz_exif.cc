// SPDX-License-Identifier: BSD-3-Clause
// Photo metadata: EXIF and XMP through GDAL's JPEG driver (GPS, focal
// length, DJI gimbal and RTK tags).
#include "libphoto/ingest/image_metadata.h"
#include "tests/fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = aerotri::fuzz::WriteInput("photo.jpg", data, size);
  aerotri::fuzz::ExpectOnlyCleanErrors([&] { aerotri::ReadImageMetadata(path); });
  return 0;
}
