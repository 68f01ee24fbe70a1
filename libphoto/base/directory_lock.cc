// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/base/directory_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

#include "libphoto/base/error.h"

namespace aerotri {
namespace fs = std::filesystem;

DirectoryLock::DirectoryLock(const fs::path& folder, Mode mode) : path_(folder / ".aerotri.lock") {
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec) throw IoError(folder.string(), "cannot create the folder: " + ec.message());
  fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) throw IoError(path_.string(), std::string("cannot create the lock file: ") + std::strerror(errno));
  if (::flock(fd_, (mode == Mode::kShared ? LOCK_SH : LOCK_EX) | LOCK_NB) != 0) {
    const int err = errno;
    char holder[32] = {0};
    const ssize_t n = ::pread(fd_, holder, sizeof(holder) - 1, 0);
    std::string pid = n > 0 ? std::string(holder, static_cast<size_t>(n)) : std::string("unknown");
    while (!pid.empty() && (pid.back() == '\n' || pid.back() == ' ')) pid.pop_back();
    ::close(fd_);
    fd_ = -1;
    if (err == EWOULDBLOCK) {
      throw Error(folder.string() + ": the workspace is in use by another aerotri process (pid " + pid +
                  "); wait for it to finish or stop it, or use another --output folder");
    }
    throw IoError(path_.string(), std::string("cannot lock: ") + std::strerror(err));
  }
  if (mode == Mode::kShared) return;  // the file names an exclusive holder only
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd_, 0) != 0 || ::pwrite(fd_, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
    // The lock holds without the pid; only the message of a second process suffers.
  }
}

DirectoryLock::~DirectoryLock() {
  if (fd_ >= 0) ::close(fd_);  // releases the flock; the file stays (unlinking it would race)
}

}  // namespace aerotri
