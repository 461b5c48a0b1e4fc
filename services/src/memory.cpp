#include "mtcal/services/memory.h"

#if __has_include(<malloc.h>)
#include <malloc.h>
#endif

namespace mtcal::services {

void keepFreedMemoryForReuse() {
#if defined(M_MMAP_MAX) && defined(M_TRIM_THRESHOLD)  // glibc
  // No block of its own mapping (glibc maps a block above its threshold, at most 32 MiB, and
  // unmaps it when freed: a diagnosis of 1e6 readings frees matrices of 200 MB); a thread's arena
  // that cannot hold a block retries in the main one, whose heap grows as needed.
  mallopt(M_MMAP_MAX, 0);
  mallopt(M_TRIM_THRESHOLD, 1024 * 1024 * 1024);
#endif
}

}  // namespace mtcal::services
