// SPDX-License-Identifier: BSD-3-Clause
// The `aerotri` executable: a light front that runs `aerotri bal` itself and
// hands every other command to `aerotri-photo`, the photo pipeline's
// executable, by exec (same process id, arguments, streams and exit code).
//
// Why: the pipeline links GDAL, OpenCV and PROJ (about 160 shared
// libraries); mapping and relocating them costs a tenth of a second and
// ~50 MB at every start, which a BAL solve of a fraction of a second should
// not pay. This front links only the adjuster, the BAL reader and bzip2.
#include <glog/logging.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "libphoto/base/error.h"
#include "tools/commands.h"
#include "tools/tool_context.h"

namespace {

// The first word that is not an option: the command.
std::string CommandOf(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    if (argv[i][0] != '-') return argv[i];
  }
  return "";
}

// aerotri-photo beside this executable (build tree, or an install's bin/),
// else in the install's libexec/aerotri/.
std::filesystem::path PhotoExecutable() {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return "aerotri-photo";
  const std::filesystem::path dir = self.parent_path();
  for (const std::filesystem::path& candidate :
       {dir / "aerotri-photo", dir / ".." / "libexec" / "aerotri" / "aerotri-photo"}) {
    if (::access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return dir / "aerotri-photo";
}

int RunBalHere(int argc, char** argv) {
  using namespace aerotri;
  // Ceres reports through glog; aerotri reports through its own summaries.
  google::InitGoogleLogging(argv[0]);
  FLAGS_minloglevel = google::GLOG_FATAL;
  CLI::App app{"aerotri: aerial triangulation and survey deliverables from drone photos."};
  app.name("aerotri");
  ToolContext ctx;
  ctx.command_line.assign(argv, argv + argc);
  app.add_flag("--quiet,-q", ctx.quiet, "Silence progress on stderr");
  app.require_subcommand(1);
  app.fallthrough();
  CommandAction run;
  RegisterBalCommand(app, &run);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  if (!run) return 2;
  try {
    return run(ctx);
  } catch (const InternalError& e) {
    std::cerr << "aerotri: " << e.what() << "\n";
  } catch (const Error& e) {
    std::cerr << "aerotri: error: " << e.what() << "\n";
  } catch (const std::bad_alloc&) {
    std::cerr << "aerotri: error: out of memory\n";
  } catch (const std::exception& e) {
    std::cerr << "aerotri: error: " << e.what() << "\n";
  }
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (CommandOf(argc, argv) == "bal") return RunBalHere(argc, argv);
  const std::filesystem::path photo = PhotoExecutable();
  std::vector<char*> args(argv, argv + argc);
  args.push_back(nullptr);
  ::execv(photo.c_str(), args.data());
  std::cerr << "aerotri: error: cannot start " << photo.string() << " (the photo pipeline's executable, installed "
            << "beside aerotri): " << std::strerror(errno) << "\n";
  return 1;
}
