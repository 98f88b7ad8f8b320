// Include in the one file of a program that defines main(): registers
// core::set_pool_environment to run before any shared library's constructor
// (libgomp and OpenBLAS size and tune their pools there, from the
// environment). Executables only: the loader ignores .preinit_array in
// shared libraries.
#pragma once
#include "core/threads.h"

namespace ddhgs::core::detail {
inline void early_setup(int, char**, char**) {
  set_pool_environment();
}
__attribute__((section(".preinit_array"),
               used)) static void (*early_setup_entry)(int, char**, char**) = early_setup;
}  // namespace ddhgs::core::detail
