// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#ifndef AEROTRI_VERSION
#error "AEROTRI_VERSION is defined by tools/CMakeLists.txt from project(VERSION)"
#endif

namespace aerotri {
inline constexpr const char* kAerotriVersion = AEROTRI_VERSION;
}
