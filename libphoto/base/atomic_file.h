// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Atomic file output: write to a temporary name beside the target, flush, then
// rename over the target. An interrupted run leaves either the old file or the
// new one, never half a file. Throws IoError naming the path on failure.

#include <filesystem>
#include <functional>
#include <ostream>
#include <string>
#include <vector>

namespace aerotri {

// Calls write(stream) on a temporary file next to path and renames it to path
// when write returns normally and the stream is good. On an exception the
// temporary file is removed and the exception propagates.
void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(std::ostream&)>& write);

// Writes text to path atomically.
void WriteTextFileAtomically(const std::filesystem::path& path,
                             const std::string& text);

// For writers that need a file name (GDAL, LAS): returns a temporary path in
// the same folder; CommitTemporaryFile() renames it onto the target.
std::filesystem::path TemporaryPathFor(const std::filesystem::path& path);
void CommitTemporaryFile(const std::filesystem::path& temporary,
                         const std::filesystem::path& path);

// Removes, anywhere under folder, what a killed writer leaves behind: the
// temporary files above (NAME.tmp.<pid>.<n>, with GDAL's NAME.tmp.<pid>.<n>.aux.xml, a
// GeoPackage's NAME.tmp.<pid>.<n>.gpkg and an orthomosaic's .building.tif)
// and GDAL's fill-nodata work files (_<pid>_..fill.._work.tif). Only for a
// folder this process holds a DirectoryLock on, where no other writer can be
// at work. Returns the paths removed.
std::vector<std::filesystem::path> RemoveStaleTemporaryFiles(const std::filesystem::path& folder);

// Reads a whole file (throws IoError naming the path when it cannot).
std::string ReadTextFile(const std::filesystem::path& path);

}  // namespace aerotri
