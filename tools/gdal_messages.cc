// SPDX-License-Identifier: BSD-3-Clause
// GDAL's messages through the tool's own: without a handler GDAL prints raw
// "Warning 1: ..." / "ERROR 1: ..." lines on stderr that name no command and
// ignore --quiet's contract (warnings shown, noise not).
#include <cpl_error.h>

#include <mutex>

#include "tools/commands.h"

namespace aerotri {
namespace {

std::mutex gdal_message_mutex;

void CPL_STDCALL ToToolContext(CPLErr level, CPLErrorNum, const char* message) {
  auto* ctx = static_cast<const ToolContext*>(CPLGetErrorHandlerUserData());
  if (!ctx || level == CE_Debug || level == CE_None) return;
  // A failure libphoto cannot recover from becomes its own error naming the
  // file; what reaches here is worth a warning either way.
  std::lock_guard<std::mutex> lock(gdal_message_mutex);  // GDAL reports from worker threads too
  ctx->Warn(std::string("GDAL: ") + (message ? message : ""));
}

}  // namespace

void RouteGdalMessages(const ToolContext* ctx) {
  if (ctx) {
    CPLSetErrorHandlerEx(ToToolContext, const_cast<ToolContext*>(ctx));
  } else {
    CPLSetErrorHandler(nullptr);  // GDAL's default again
  }
}

}  // namespace aerotri
