// Large blocks on transparent huge pages. A dense scan's working arrays (points, normals,
// labels, grids: tens of MB) are allocated and zero-filled stage after stage; with 4 kB pages
// each first touch is a page fault (~5 % of the CPU time of a 1M-point detection). Blocks of
// 2 MB and more are advised as huge-page memory (MADV_HUGEPAGE: honoured where
// /sys/kernel/mm/transparent_hugepage/enabled is "always" or "madvise", the Debian default;
// a no-op otherwise). The same as glibc's glibc.malloc.hugetlb=1 tunable, which only an
// environment variable set before the process starts can turn on.
// Replacing the global operator new in the executable replaces it for the plugins too (they
// resolve it through the executable's dynamic symbols). Sanitizer builds keep their own
// operator new (its new/delete mismatch checks).
#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
#include <sys/mman.h>

#include <cstdint>
#include <algorithm>
#include <cstdlib>
#include <new>

namespace {

constexpr size_t kHuge = size_t(2) << 20;

void Advise(void* p, size_t n) {
  if (n < kHuge || p == nullptr) return;
  const uintptr_t b = (reinterpret_cast<uintptr_t>(p) + kHuge - 1) & ~uintptr_t(kHuge - 1);
  const uintptr_t e = (reinterpret_cast<uintptr_t>(p) + n) & ~uintptr_t(kHuge - 1);
  if (e > b) madvise(reinterpret_cast<void*>(b), e - b, MADV_HUGEPAGE);
}

void* Allocate(size_t n) {
  void* p = std::malloc(n == 0 ? 1 : n);
  if (!p) throw std::bad_alloc();
  Advise(p, n);
  return p;
}

void* AllocateAligned(size_t n, std::align_val_t a) {
  const size_t al = std::max(sizeof(void*), static_cast<size_t>(a));
  void* p = nullptr;
  if (posix_memalign(&p, al, n == 0 ? 1 : n) != 0) throw std::bad_alloc();
  Advise(p, n);
  return p;
}

}  // namespace

void* operator new(size_t n) { return Allocate(n); }
void* operator new[](size_t n) { return Allocate(n); }
void* operator new(size_t n, const std::nothrow_t&) noexcept {
  try {
    return Allocate(n);
  } catch (...) {
    return nullptr;
  }
}
void* operator new[](size_t n, const std::nothrow_t&) noexcept {
  try {
    return Allocate(n);
  } catch (...) {
    return nullptr;
  }
}
void* operator new(size_t n, std::align_val_t a) { return AllocateAligned(n, a); }
void* operator new[](size_t n, std::align_val_t a) { return AllocateAligned(n, a); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, size_t) noexcept { std::free(p); }
void operator delete[](void* p, size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, size_t, std::align_val_t) noexcept { std::free(p); }
#endif
