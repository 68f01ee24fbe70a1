// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/survey/findings.h"

#include <utility>

namespace aerotri {

Finding Finding::Warning(std::string code, std::string message, std::vector<std::string> items) {
  return {Severity::kWarning, std::move(code), std::move(message), std::move(items)};
}

Finding Finding::Error(std::string code, std::string message, std::vector<std::string> items) {
  return {Severity::kError, std::move(code), std::move(message), std::move(items)};
}

std::string SurveyStatus(const std::vector<Finding>& findings) {
  if (findings.empty()) return "ok";
  for (const Finding& f : findings) {
    if (f.severity == Severity::kError) return "failed";
  }
  return "warnings";
}

std::string JoinNames(const std::vector<std::string>& names, size_t max) {
  std::string out;
  for (size_t k = 0; k < names.size() && k < max; ++k) out += (k ? ", " : "") + names[k];
  if (names.size() > max) out += " (and " + std::to_string(names.size() - max) + " more)";
  return out;
}

}  // namespace aerotri
