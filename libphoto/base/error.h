// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The error family of aerotri (see STYLE.md, "Errors, in three tiers").
//
//  1. "No answer" is a value (std::optional, a summary's termination reason).
//  2. Bad input is one of the exceptions below; the message says what was read,
//     where, and what was expected, so that a surveyor can act on it:
//       gcp_list.txt:7: expected 6 or 7 columns, got 5
//  3. A broken invariant is a bug: AEROTRI_CHECK throws InternalError with the
//     source file and line.
//
// The library never aborts or exits on user data; the command line maps
// aerotri::Error to exit code 1 and usage errors to 2.

#include <stdexcept>
#include <string>

namespace aerotri {

// Base of every error aerotri raises on purpose.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

// A value outside its allowed range (an option, a parameter).
class InvalidArgument : public Error {
 public:
  using Error::Error;
};

// A command line that asks for something contradictory (exit code 2, as a
// usage error): e.g. the control file passed again as the check file.
class UsageError : public Error {
 public:
  using Error::Error;
};

// A file that cannot be opened, read or written.
class IoError : public Error {
 public:
  IoError(const std::string& path, const std::string& what)
      : Error(path + ": " + what), path_(path) {}
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// A file whose content does not follow its format. line is 1-based; 0 when the
// error is not tied to one line (e.g. a truncated file).
class ParseError : public Error {
 public:
  ParseError(const std::string& path, int line, const std::string& what)
      : Error(path + (line > 0 ? ":" + std::to_string(line) : std::string()) +
              ": " + what),
        path_(path),
        line_(line) {}
  const std::string& path() const { return path_; }
  int line() const { return line_; }

 private:
  std::string path_;
  int line_;
};

// A coordinate reference system that PROJ cannot create or transform with.
class CrsError : public Error {
 public:
  using Error::Error;
};

// A broken invariant: a bug in aerotri, not bad input.
class InternalError : public Error {
 public:
  using Error::Error;
};

// An option's check, as the options structs' Check() methods use it: when
// !ok, throws InvalidArgument "OPTION: expected EXPECTED, got VALUE". option
// is spelt as on the command line ("--dense-min-views").
void CheckOption(bool ok, const std::string& option, double value, const std::string& expected);
void CheckOption(bool ok, const std::string& option, const std::string& value, const std::string& expected);

[[noreturn]] void ThrowInternalError(const char* file, int line,
                                     const char* condition,
                                     const std::string& detail = {});

}  // namespace aerotri

// Checks an invariant; a failure is a bug and throws aerotri::InternalError.
#define AEROTRI_CHECK(cond)                                        \
  do {                                                             \
    if (!(cond)) ::aerotri::ThrowInternalError(__FILE__, __LINE__, #cond); \
  } while (false)

#define AEROTRI_CHECK_MSG(cond, msg)                               \
  do {                                                             \
    if (!(cond))                                                   \
      ::aerotri::ThrowInternalError(__FILE__, __LINE__, #cond, (msg)); \
  } while (false)
