// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Reads a file into memory, decompressing bzip2 (recognised by its "BZh"
// magic, whatever the extension) through libbz2. Throws IoError naming the
// path when the file cannot be read or the bzip2 stream is corrupt or
// truncated.

#include <filesystem>
#include <string>

namespace aerotri {

std::string ReadMaybeCompressedFile(const std::filesystem::path& path);

}  // namespace aerotri
