// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// A fast whitespace-separated number scanner over an in-memory text that
// keeps the current line number, so that a parse error can name it.
// Uses std::from_chars (locale-independent, no allocation).

#include <charconv>
#include <cstdint>
#include <string>
#include <string_view>

#include "libphoto/base/error.h"

namespace aerotri {

class TextScanner {
 public:
  TextScanner(std::string_view text, std::string path)
      : p_(text.data()), end_(text.data() + text.size()), path_(std::move(path)) {}

  int line() const { return line_; }
  const std::string& path() const { return path_; }
  bool AtEnd() {
    SkipSpace();
    return p_ == end_;
  }

  // Reads the next number; `what` names it in the error message.
  double Double(const char* what) {
    SkipSpace();
    double value = 0.0;
    const auto [next, ec] = std::from_chars(p_, end_, value);
    if (ec != std::errc() || next == p_) Fail(what, "a number");
    p_ = next;
    return value;
  }

  std::int64_t Integer(const char* what) {
    SkipSpace();
    std::int64_t value = 0;
    const auto [next, ec] = std::from_chars(p_, end_, value);
    if (ec != std::errc() || next == p_ || (next != end_ && (*next == '.' || *next == 'e'))) {
      Fail(what, "an integer");
    }
    p_ = next;
    return value;
  }

  [[noreturn]] void Fail(const char* what, const char* expected) {
    if (p_ == end_) {
      throw ParseError(path_, line_, std::string("unexpected end of file while reading ") +
                                         what + " (the file is truncated)");
    }
    const char* token_end = p_;
    while (token_end != end_ && !IsSpace(*token_end) && token_end - p_ < 40) ++token_end;
    throw ParseError(path_, line_, std::string("expected ") + expected + " for " + what +
                                       ", got '" + std::string(p_, token_end) + "'");
  }

 private:
  static bool IsSpace(char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
  }
  void SkipSpace() {
    while (p_ != end_ && IsSpace(*p_)) {
      if (*p_ == '\n') ++line_;
      ++p_;
    }
  }

  const char* p_;
  const char* end_;
  std::string path_;
  int line_ = 1;
};

}  // namespace aerotri
