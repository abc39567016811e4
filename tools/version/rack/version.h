// The version every tool prints for --version: the CMake project version and, in a
// git checkout, `git describe` (generated into version.cpp at each build, so that only
// that one file recompiles when a commit changes it). Not RT code (print_version prints).
#pragma once

namespace rack {

[[nodiscard]] const char* version() noexcept;       // "0.1.0"
[[nodiscard]] const char* git_describe() noexcept;  // "478da5c-dirty"; "" outside git

// "rackd 0.1.0 (git 478da5c-dirty)" on stdout: the line of every tool's --version.
void print_version(const char* tool);

}  // namespace rack
