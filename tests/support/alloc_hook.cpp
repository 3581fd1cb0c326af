// Counts heap allocations and releases made by an armed thread: replaces the
// global operator new/delete and (on glibc, without sanitizers) malloc/free
// themselves. Link it only into a test binary of its own, so that the hooks
// cannot disturb other tests. See alloc_hook.h.
#include "alloc_hook.h"

#include <dlfcn.h>
#include <pthread.h>
#include <sys/resource.h>

#include <atomic>
#include <cstdlib>
#include <new>

namespace {
// Armed per thread: only the thread under test (the audio thread) counts, so
// other threads (simulation, game) may allocate freely meanwhile.
thread_local bool tArmed = false;
std::atomic<long> gAllocs{0};
std::atomic<long> gFrees{0};
std::atomic<long> gLocks{0};

void noteAlloc() {
  if (tArmed) gAllocs.fetch_add(1, std::memory_order_relaxed);
}
void noteFree(void* p) {
  if (p && tArmed) gFrees.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
#define EARSHOT_HOOK_MALLOC 1
extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);
void __libc_free(void*);

void* malloc(size_t n) {
  noteAlloc();
  return __libc_malloc(n);
}
void* calloc(size_t a, size_t b) {
  noteAlloc();
  return __libc_calloc(a, b);
}
void* realloc(void* p, size_t n) {
  noteAlloc();
  return __libc_realloc(p, n);
}
void free(void* p) {
  noteFree(p);
  __libc_free(p);
}
void* aligned_alloc(size_t al, size_t n) {
  noteAlloc();
  return __libc_memalign(al, n);
}
void* memalign(size_t al, size_t n) {
  noteAlloc();
  return __libc_memalign(al, n);
}
int posix_memalign(void** out, size_t al, size_t n) {
  noteAlloc();
  void* p = __libc_memalign(al, n);
  if (!p) return 12;  // ENOMEM
  *out = p;
  return 0;
}

// Locks: std::mutex, condition variables' mutexes and shared_mutex end in
// these; the real functions are found with dlsym(RTLD_NEXT) at load time.
using MutexFn = int (*)(pthread_mutex_t*);
using RwlockFn = int (*)(pthread_rwlock_t*);
static MutexFn gRealMutexLock = reinterpret_cast<MutexFn>(dlsym(RTLD_NEXT, "pthread_mutex_lock"));
static MutexFn gRealMutexTrylock = reinterpret_cast<MutexFn>(dlsym(RTLD_NEXT, "pthread_mutex_trylock"));
static RwlockFn gRealRdlock = reinterpret_cast<RwlockFn>(dlsym(RTLD_NEXT, "pthread_rwlock_rdlock"));
static RwlockFn gRealWrlock = reinterpret_cast<RwlockFn>(dlsym(RTLD_NEXT, "pthread_rwlock_wrlock"));
int pthread_mutex_lock(pthread_mutex_t* m) {
  if (tArmed) gLocks.fetch_add(1, std::memory_order_relaxed);
  if (!gRealMutexLock) gRealMutexLock = reinterpret_cast<MutexFn>(dlsym(RTLD_NEXT, "pthread_mutex_lock"));
  return gRealMutexLock(m);
}
int pthread_mutex_trylock(pthread_mutex_t* m) {
  if (tArmed) gLocks.fetch_add(1, std::memory_order_relaxed);
  if (!gRealMutexTrylock) gRealMutexTrylock = reinterpret_cast<MutexFn>(dlsym(RTLD_NEXT, "pthread_mutex_trylock"));
  return gRealMutexTrylock(m);
}
int pthread_rwlock_rdlock(pthread_rwlock_t* l) {
  if (tArmed) gLocks.fetch_add(1, std::memory_order_relaxed);
  if (!gRealRdlock) gRealRdlock = reinterpret_cast<RwlockFn>(dlsym(RTLD_NEXT, "pthread_rwlock_rdlock"));
  return gRealRdlock(l);
}
int pthread_rwlock_wrlock(pthread_rwlock_t* l) {
  if (tArmed) gLocks.fetch_add(1, std::memory_order_relaxed);
  if (!gRealWrlock) gRealWrlock = reinterpret_cast<RwlockFn>(dlsym(RTLD_NEXT, "pthread_rwlock_wrlock"));
  return gRealWrlock(l);
}
}
#endif

// operator new/delete on top of malloc/free (counted once there when the
// malloc hook is active, here otherwise).
#ifdef EARSHOT_HOOK_MALLOC
#define COUNT_NEW()
#define COUNT_DELETE(p)
#else
#define COUNT_NEW() noteAlloc()
#define COUNT_DELETE(p) noteFree(p)
#endif
void* operator new(size_t n) {
  COUNT_NEW();
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](size_t n) { return operator new(n); }
void* operator new(size_t n, const std::nothrow_t&) noexcept {
  COUNT_NEW();
  return std::malloc(n ? n : 1);
}
void* operator new[](size_t n, const std::nothrow_t& t) noexcept { return operator new(n, t); }
void* operator new(size_t n, std::align_val_t al) {
  COUNT_NEW();
  size_t a = static_cast<size_t>(al);
  if (void* p = std::aligned_alloc(a, (n + a - 1) / a * a)) return p;
  throw std::bad_alloc();
}
void* operator new[](size_t n, std::align_val_t al) { return operator new(n, al); }
void operator delete(void* p) noexcept {
  COUNT_DELETE(p);
  std::free(p);
}
void operator delete[](void* p) noexcept { operator delete(p); }
void operator delete(void* p, size_t) noexcept { operator delete(p); }
void operator delete[](void* p, size_t) noexcept { operator delete(p); }
void operator delete(void* p, std::align_val_t) noexcept { operator delete(p); }
void operator delete[](void* p, std::align_val_t) noexcept { operator delete(p); }
void operator delete(void* p, size_t, std::align_val_t) noexcept { operator delete(p); }
void operator delete[](void* p, size_t, std::align_val_t) noexcept { operator delete(p); }


namespace earshot::test {

AllocationCounter::AllocationCounter() {
  gAllocs = 0;
  gFrees = 0;
  gLocks = 0;
  tArmed = true;
}
AllocationCounter::~AllocationCounter() { tArmed = false; }
long AllocationCounter::allocations() const { return gAllocs.load(); }
long AllocationCounter::releases() const { return gFrees.load(); }
long AllocationCounter::locks() const { return gLocks.load(); }
void AllocationCounter::pause() { tArmed = false; }
void AllocationCounter::resume() { tArmed = true; }

bool mallocIsHooked() {
#ifdef EARSHOT_HOOK_MALLOC
  return true;
#else
  return false;
#endif
}

long threadPageFaults() {
  rusage ru{};
  if (getrusage(RUSAGE_THREAD, &ru) != 0) return -1;
  return ru.ru_minflt + ru.ru_majflt;
}

}  // namespace earshot::test
