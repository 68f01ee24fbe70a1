// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/base/error.h"

#include <sstream>

namespace aerotri {

void CheckOption(bool ok, const std::string& option, double value, const std::string& expected) {
  if (ok) return;
  std::ostringstream got;
  got << value;  // shortest form: 0.5, 1e-06, nan
  throw InvalidArgument(option + ": expected " + expected + ", got " + got.str());
}

void CheckOption(bool ok, const std::string& option, const std::string& value, const std::string& expected) {
  if (!ok) throw InvalidArgument(option + ": expected " + expected + ", got '" + value + "'");
}

void ThrowInternalError(const char* file, int line, const char* condition,
                        const std::string& detail) {
  std::string message = std::string("internal error at ") + file + ":" +
                        std::to_string(line) + ": check failed: " + condition;
  if (!detail.empty()) message += " (" + detail + ")";
  message += "; please report this as a bug";
  throw InternalError(message);
}

}  // namespace aerotri
