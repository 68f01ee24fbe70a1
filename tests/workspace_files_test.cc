// SPDX-License-Identifier: BSD-3-Clause
// The workspace lock and the clean-up of what a killed run leaves behind.
#include <unistd.h>

#include <fstream>
#include <string>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/directory_lock.h"
#include "libphoto/base/error.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

namespace fs = std::filesystem;

TEST(DirectoryLock, SecondHolderIsRefusedWithThePidUntilTheFirstLetsGo) {
  testing::TempDir dir;
  const fs::path ws = dir.path() / "survey";
  {
    const DirectoryLock first(ws);  // creates the folder
    EXPECT_TRUE(fs::is_directory(ws));
    // flock locks belong to the open file: a second open conflicts even in this process.
    try {
      const DirectoryLock second(ws);
      ADD_FAILURE() << "a second lock on a held workspace was granted";
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(ws.string() + ": the workspace is in use by another aerotri process (pid " +
                          std::to_string(::getpid()) + ")"),
                std::string::npos)
          << what;
    }
  }
  EXPECT_NO_THROW(DirectoryLock again(ws));  // released with its holder
}

// A split workflow's dense shares work in one workspace at once (shared),
// and nothing exclusive (a run, a stage) starts beside them, nor they beside it.
TEST(DirectoryLock, SharedHoldersCoexistButExcludeAnExclusiveOne) {
  testing::TempDir dir;
  const fs::path ws = dir.path() / "survey";
  {
    const DirectoryLock a(ws, DirectoryLock::Mode::kShared);
    EXPECT_NO_THROW(DirectoryLock b(ws, DirectoryLock::Mode::kShared));
    EXPECT_THROW(DirectoryLock exclusive(ws), Error);
  }
  {
    const DirectoryLock exclusive(ws);
    EXPECT_THROW(DirectoryLock shared(ws, DirectoryLock::Mode::kShared), Error);
  }
  EXPECT_NO_THROW(DirectoryLock shared(ws, DirectoryLock::Mode::kShared));
}

TEST(DirectoryLock, UncreatableFolderIsAnIoErrorNamingIt) {
  testing::TempDir dir;
  std::ofstream(dir.path() / "a_file") << "x";
  EXPECT_THROW(DirectoryLock(dir.path() / "a_file" / "ws"), IoError);
}

TEST(RemoveStaleTemporaryFiles, RemovesWhatKilledWritersLeaveAndNothingElse) {
  testing::TempDir dir;
  const fs::path ws = dir.path();
  fs::create_directories(ws / "depth");
  const std::vector<std::string> stale = {"dsm.tif.tmp.4242.0", "dsm.tif.tmp.4242.0.aux.xml",
                                          "depth/IMG_1.bin.tmp.17.3", "_4242_1fill_0_work.tif",
                                          "contours.gpkg.tmp.4242.1.gpkg", "ortho.tif.tmp.4242.2.building.tif"};
  const std::vector<std::string> kept = {"dsm.tif", "cloud.las", "depth/IMG_1.bin", "notes.tmp.txt",
                                         "report.json.tmp", "IMG.tmp.12.jpg", ".aerotri.lock"};
  for (const auto& f : stale) std::ofstream(ws / f) << "x";
  for (const auto& f : kept) std::ofstream(ws / f) << "x";
  const auto removed = RemoveStaleTemporaryFiles(ws);
  EXPECT_EQ(removed.size(), stale.size());
  for (const auto& f : stale) EXPECT_FALSE(fs::exists(ws / f)) << f;
  for (const auto& f : kept) EXPECT_TRUE(fs::exists(ws / f)) << f;
  EXPECT_TRUE(RemoveStaleTemporaryFiles(ws / "no_such_folder").empty());
}

// A temporary name made by TemporaryPathFor is one the clean-up recognises.
TEST(RemoveStaleTemporaryFiles, RecognisesTheWritersOwnTemporaryNames) {
  testing::TempDir dir;
  const fs::path tmp = TemporaryPathFor(dir.path() / "cloud.las");
  std::ofstream(tmp) << "half a file";
  ASSERT_EQ(RemoveStaleTemporaryFiles(dir.path()).size(), 1u);
  EXPECT_FALSE(fs::exists(tmp));
}

}  // namespace
}  // namespace aerotri
