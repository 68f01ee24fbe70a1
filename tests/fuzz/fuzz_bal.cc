// SPDX-License-Identifier: BSD-3-Clause
// BAL problems, plain text or bzip2 (told apart by content, as `aerotri bal` does).
#include "libphoto/io/bal.h"
#include "tests/fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = aerotri::fuzz::WriteInput("problem.txt", data, size);
  aerotri::fuzz::ExpectOnlyCleanErrors([&] { aerotri::ReadBalProblem(path); });
  return 0;
}
