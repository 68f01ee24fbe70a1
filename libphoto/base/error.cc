// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/base/error.h"

namespace aerotri {

void ThrowInternalError(const char* file, int line, const char* condition,
                        const std::string& detail) {
  std::string message = std::string("internal error at ") + file + ":" +
                        std::to_string(line) + ": check failed: " + condition;
  if (!detail.empty()) message += " (" + detail + ")";
  message += "; please report this as a bug";
  throw InternalError(message);
}

}  // namespace aerotri
