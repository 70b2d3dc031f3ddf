// The CLI's global operator new and delete: every block from allocate_on_huge_pages (volume.h),
// so that, where huge pages pay on the machine (huge_pages_advised), the whole 2 MiB pages inside
// one of 2 MiB or more are transparent huge pages. A large buffer (a queue, a mesh's arrays, a
// component labelling, a file read whole) is then first touched in far fewer page faults, which
// under some hypervisors cost ~12 us each. Smaller blocks are malloc's, from a heap main() asks for
// as huge pages too in that case (tune_heap_for_volumes). Not under AddressSanitizer, which brings
// its own operator new.
#include "endocast/volume.h"  // ENDOCAST_UNDER_ASAN

#if defined(__linux__) && !defined(ENDOCAST_UNDER_ASAN)
#include <cstddef>
#include <new>

void* operator new(size_t n) { return endocast::allocate_voxel_memory(n); }
void* operator new[](size_t n) { return endocast::allocate_voxel_memory(n); }
void* operator new(size_t n, const std::nothrow_t&) noexcept { return endocast::allocate_on_huge_pages(n); }
void* operator new[](size_t n, const std::nothrow_t&) noexcept { return endocast::allocate_on_huge_pages(n); }
void operator delete(void* p) noexcept { endocast::free_voxel_memory(p); }
void operator delete[](void* p) noexcept { endocast::free_voxel_memory(p); }
void operator delete(void* p, size_t) noexcept { endocast::free_voxel_memory(p); }
void operator delete[](void* p, size_t) noexcept { endocast::free_voxel_memory(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { endocast::free_voxel_memory(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { endocast::free_voxel_memory(p); }
#endif
