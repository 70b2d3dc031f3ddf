// Force-included (-include) before io.cpp in the fuzz build only. Debian's ITK 5.2 headers were
// generated for GCC alone: itk_compiler_detection.h stops with "#error Unsupported compiler" under
// clang. ITK itself was built by GCC 12, so its detection header is read here as GCC 12 would read
// it (its macros only select C++11 spellings such as alignas, which clang has as well); every
// macro touched is restored afterwards, so the rest of io.cpp sees clang as clang.
#pragma once
#pragma push_macro("__clang__")
#pragma push_macro("__GNUC__")
#pragma push_macro("__GNUC_MINOR__")
#undef __clang__
#undef __GNUC__
#undef __GNUC_MINOR__
#define __GNUC__ 12
#define __GNUC_MINOR__ 2
#include <itk_compiler_detection.h>
#pragma pop_macro("__GNUC_MINOR__")
#pragma pop_macro("__GNUC__")
#pragma pop_macro("__clang__")
