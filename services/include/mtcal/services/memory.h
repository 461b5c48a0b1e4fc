#pragma once
// How a front end's process hands memory back to the system.

namespace mtcal::services {

/// Keeps large freed blocks in the process for reuse instead of returning them to the kernel
/// (glibc: blocks up to 32 MiB from the heap, the heap not trimmed below 1 GiB of free
/// memory). A numerical process allocates and frees matrices of the same large sizes again
/// and again (a diagnosis of 1e5 readings: thousands of 20 MB temporaries); glibc's defaults
/// return each to the kernel, which then clears every page of the next one as it is touched.
/// That was 40 % of such a diagnosis' time (docs/performance.md). The price: the process keeps
/// its peak memory until it ends. Call once, at the start of main; elsewhere than glibc it does
/// nothing.
void keepFreedMemoryForReuse();

}  // namespace mtcal::services
