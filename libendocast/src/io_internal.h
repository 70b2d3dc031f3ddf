#pragma once
// Shared by the readers in io.cpp and raw_io.cpp (not installed).
#include <cstddef>

#include "endocast/io.h"

namespace endocast {

/// Converts n stored samples of type t at src (bytes reversed if `swap`) to float, one thread.
void convert_samples(RawType t, const unsigned char* src, size_t n, bool swap, float* dst);

}  // namespace endocast
