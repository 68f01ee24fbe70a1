// SPDX-License-Identifier: BSD-3-Clause
// The aerotri command line: one binary, subcommands. Exit codes: 0 success,
// 1 runtime or data error, 2 usage error.
#include <glog/logging.h>
#include <unistd.h>

#include <csignal>

#include <CLI/CLI.hpp>
#include <iostream>
#include <string>

#include "libphoto/base/error.h"
#include "tools/commands.h"
#include "tools/tool_context.h"

int main(int argc, char** argv) {
  using namespace aerotri;
  // Ceres reports through glog; aerotri reports through its own summaries.
  google::InitGoogleLogging(argv[0]);
  FLAGS_minloglevel = google::GLOG_FATAL;
  CLI::App app{
      "aerotri: aerial triangulation and survey deliverables from drone photos.\n"
      "Progress goes to stderr, data to stdout. Exit codes: 0 ok, 1 runtime/data error, "
      "2 usage error."};
  app.name("aerotri");
  // A file-size limit (ulimit -f) or a quota then fails the write with EFBIG,
  // which the writer reports naming the file, instead of SIGXFSZ killing the
  // process with a core dump and no word.
  std::signal(SIGXFSZ, SIG_IGN);
  ToolContext ctx;
  ctx.rewrite_progress = ::isatty(STDERR_FILENO) != 0;
  ctx.command_line.assign(argv, argv + argc);
  app.add_flag("--quiet,-q", ctx.quiet, "Silence progress on stderr");
  RouteGdalMessages(&ctx);
  app.set_version_flag("--version", VersionString());
  app.require_subcommand(1);
  app.fallthrough();  // --quiet also after the subcommand

  CommandAction run;
  RegisterBalCommand(app, &run);
  RegisterAdjustCommand(app, &run);
  RegisterSimulateCommand(app, &run);
  RegisterRunCommands(app, &run);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    if (app.get_subcommands().empty()) {
      // No command recognised: name the word that was taken for one.
      for (int i = 1; i < argc; ++i) {
        const std::string word = argv[i];
        if (word.empty() || word[0] == '-') continue;
        std::string commands;
        for (const CLI::App* sub : app.get_subcommands({})) {
          commands += (commands.empty() ? "" : ", ") + sub->get_name();
        }
        std::cerr << "aerotri: unknown command '" << word << "'; the commands are " << commands
                  << " (aerotri --help)\n";
        return 2;
      }
    }
    app.exit(e);
    return 2;
  }
  if (!run) {
    std::cerr << app.help();
    return 2;
  }
  try {
    const int code = run(ctx);
    ctx.CloseLine();
    return code;
  } catch (const InternalError& e) {
    ctx.CloseLine();
    std::cerr << "aerotri: " << e.what() << "\n";
    return 1;
  } catch (const UsageError& e) {
    ctx.CloseLine();
    std::cerr << "aerotri: error: " << e.what() << "\n";
    return 2;
  } catch (const Error& e) {
    ctx.CloseLine();
    std::cerr << "aerotri: error: " << e.what() << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    std::cerr << "aerotri: error: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "aerotri: error: " << e.what() << "\n";
    return 1;
  }
}
