// SPDX-License-Identifier: BSD-3-Clause
// COLMAP text models: the input is split at two "\n===\n" separators into
// cameras.txt, images.txt and points3D.txt.
#include <string>

#include "libphoto/io/colmap_text.h"
#include "tests/fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string input(reinterpret_cast<const char*>(data), size);
  const std::string sep = "\n===\n";
  std::string parts[3];
  size_t begin = 0;
  for (int k = 0; k < 3; ++k) {
    const size_t end = k < 2 ? input.find(sep, begin) : std::string::npos;
    parts[k] = input.substr(begin, end == std::string::npos ? std::string::npos : end - begin);
    if (end == std::string::npos) break;
    begin = end + sep.size();
  }
  const auto dir = aerotri::fuzz::WorkDir() / "model";
  std::filesystem::create_directories(dir);
  const char* names[3] = {"model/cameras.txt", "model/images.txt", "model/points3D.txt"};
  for (int k = 0; k < 3; ++k) {
    aerotri::fuzz::WriteInput(names[k], reinterpret_cast<const uint8_t*>(parts[k].data()), parts[k].size());
  }
  aerotri::fuzz::ExpectOnlyCleanErrors([&] { aerotri::ReadColmapText(dir); });
  return 0;
}
