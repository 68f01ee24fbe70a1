// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// An advisory lock on a folder (flock on FOLDER/.aerotri.lock holding the
// holder's pid), so that two aerotri processes never work on one survey
// workspace at once. The lock is the open file: it goes away with the
// process, also when the process is killed, so no stale lock can remain.

#include <filesystem>

namespace aerotri {

class DirectoryLock {
 public:
  // Creates the folder if needed and takes the lock without waiting. Throws
  // Error naming the folder and the holder's pid when another process holds
  // it, IoError when the lock file cannot be created.
  //
  // Shared: several holders at once (the jobs of a workflow that each write
  // only their own share of the workspace), none while an exclusive holder
  // works, and no exclusive holder while any shared one does.
  enum class Mode { kExclusive, kShared };
  explicit DirectoryLock(const std::filesystem::path& folder, Mode mode = Mode::kExclusive);
  ~DirectoryLock();
  DirectoryLock(const DirectoryLock&) = delete;
  DirectoryLock& operator=(const DirectoryLock&) = delete;

  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
  int fd_ = -1;
};

}  // namespace aerotri
