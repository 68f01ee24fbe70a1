// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/base/atomic_file.h"

#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <regex>
#include <sstream>

#include "libphoto/base/error.h"

namespace aerotri {
namespace fs = std::filesystem;

fs::path TemporaryPathFor(const fs::path& path) {
  static std::atomic<int> counter{0};
  fs::path tmp = path;
  tmp += ".tmp." + std::to_string(::getpid()) + "." +
         std::to_string(counter.fetch_add(1));
  return tmp;
}

std::vector<fs::path> RemoveStaleTemporaryFiles(const fs::path& folder) {
  static const std::regex temporary(R"(.*\.tmp\.[0-9]+\.[0-9]+(\.aux\.xml|\.gpkg|\.building\.tif)?)");
  static const std::regex gdal_work(R"(_[0-9]+_.*fill.*_work\.tif)");
  std::vector<fs::path> removed;
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) return removed;
  for (auto it = fs::recursive_directory_iterator(folder, fs::directory_options::skip_permission_denied, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (!it->is_regular_file(ec)) continue;
    const std::string name = it->path().filename().string();
    if (std::regex_match(name, temporary) || std::regex_match(name, gdal_work)) removed.push_back(it->path());
  }
  for (const fs::path& p : removed) fs::remove(p, ec);
  return removed;
}

void CommitTemporaryFile(const fs::path& temporary, const fs::path& path) {
  std::error_code ec;
  fs::rename(temporary, path, ec);
  if (ec) {
    fs::remove(temporary, ec);
    throw IoError(path.string(), "cannot rename the finished temporary file " +
                                     temporary.string() + " onto it: " +
                                     ec.message());
  }
}

void WriteFileAtomically(const fs::path& path,
                         const std::function<void(std::ostream&)>& write) {
  if (path.has_parent_path() && !fs::exists(path.parent_path())) {
    std::error_code ec;
    fs::create_directories(path.parent_path(), ec);
    if (ec) throw IoError(path.parent_path().string(), "cannot create folder: " + ec.message());
  }
  const fs::path tmp = TemporaryPathFor(path);
  try {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw IoError(tmp.string(), std::string("cannot open for writing: ") + std::strerror(errno));
    errno = 0;
    write(out);
    out.flush();
    if (!out) {
      // errno of the failed write: ENOSPC (disk full), EFBIG (file-size
      // limit or quota), EIO. The product is named; its temporary goes.
      const int e = errno;
      throw IoError(path.string(), std::string("write failed: ") + (e ? std::strerror(e) : "stream error") +
                                       " (disk full or a size limit?); nothing was kept of it");
    }
    out.close();
    if (!out) throw IoError(path.string(), std::string("write failed on close: ") + std::strerror(errno));
  } catch (...) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw;
  }
  CommitTemporaryFile(tmp, path);
}

void WriteTextFileAtomically(const fs::path& path, const std::string& text) {
  WriteFileAtomically(path, [&](std::ostream& out) { out << text; });
}

std::string ReadTextFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path.string(), std::string("cannot open for reading: ") + std::strerror(errno));
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) throw IoError(path.string(), "read failed");
  return buffer.str();
}

}  // namespace aerotri
