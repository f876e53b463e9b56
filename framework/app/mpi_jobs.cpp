#include "mpi_jobs.hpp"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <exception>
#include <filesystem>
#include <mutex>
#include <new>
#include <thread>

#include "furnihost/error.hpp"
#include "furnihost/log.hpp"
#include "wire.hpp"

namespace furnihost::app {

namespace {

// Message tags. Rank 0 <-> the other ranks during ShareJobs: kReady (a rank's first request:
// its host and pid), kResult (a job's result, also the next request), kFailed (a job threw:
// its kind and message); replies kJob (the next job), kDone (no more), kStop (the run failed:
// the exit code). FromRoot: kRoot (the bytes) or kRootFailed (the exit code).
enum Tag : int { kReady = 1, kJob, kResult, kFailed, kDone, kStop, kRoot, kRootFailed };

// How an exception leaves a rank, so that rank 0 throws the same kind (and exit code).
enum class Kind : int32_t { kInput = 0, kStageInput, kStage, kInternal };
Kind KindOf(std::exception_ptr e, std::string* what) {
  try {
    std::rethrow_exception(e);
  } catch (const InputError& x) {
    *what = x.what();
    return Kind::kInput;
  } catch (const StageError& x) {
    *what = x.what();
    return x.IsInputError() ? Kind::kStageInput : Kind::kStage;
  } catch (const std::filesystem::filesystem_error& x) {
    *what = x.what();
    return Kind::kInput;
  } catch (const std::bad_alloc&) {
    *what = "out of memory";
    return Kind::kInternal;
  } catch (const std::exception& x) {
    *what = x.what();
    return Kind::kInternal;
  } catch (const RankStopped& x) {
    *what = "stopped";
    return x.code == 2 ? Kind::kInput : Kind::kInternal;
  } catch (...) {
    *what = "unknown exception";
    return Kind::kInternal;
  }
}
int ExitCode(Kind k) { return k == Kind::kInput || k == Kind::kStageInput ? 2 : 1; }
[[noreturn]] void Throw(Kind k, const std::string& what) {
  switch (k) {
    case Kind::kInput: throw InputError(what);
    case Kind::kStageInput: throw StageError(what, true);
    case Kind::kStage: throw StageError(what, false);
    default: throw std::runtime_error(what);
  }
}

// ---- what each rank held, for the signal handlers (async-signal-safe: fixed buffers, write) ----
constexpr int kMaxRanks = 4096;
struct Held {
  std::atomic<long> job{-1};
  long pid = 0;
  char host[64] = "";
};
Held g_held[kMaxRanks];
const std::vector<std::string>* g_jobs = nullptr;  // job descriptions
int g_rank = 0, g_size = 1;
char g_host[64] = "";
struct sigaction g_old[32];

void Put(const char* s) {
  const size_t n = std::strlen(s);
  if (write(STDERR_FILENO, s, n) < 0) {
  }
}
void PutNum(long v) {
  char b[24];
  int i = 23;
  b[i] = '\0';
  const bool neg = v < 0;
  unsigned long u = neg ? 0ul - static_cast<unsigned long>(v) : static_cast<unsigned long>(v);
  do b[--i] = char('0' + u % 10), u /= 10;
  while (u && i > 1);
  if (neg) b[--i] = '-';
  Put(b + i);
}
void PutJob(long j) {
  Put("job ");
  PutNum(j + 1);
  Put(" of ");
  PutNum(g_jobs ? long(g_jobs->size()) : 0);
  if (g_jobs && j >= 0 && size_t(j) < g_jobs->size()) {
    Put(" (");
    Put((*g_jobs)[size_t(j)].c_str());
    Put(")");
  }
}

void Reraise(int sig) {
  sigaction(sig, &g_old[sig], nullptr);
  raise(sig);
}

// Rank 0, stopped by mpirun (or the user) while jobs run: which rank held which job, and which
// ranks on this host are gone (the one that died, when it ran here).
void RootStopped(int sig) {
  Put("furnihost: rank 0 stopped by signal ");
  PutNum(sig);
  Put(" while the ranks held jobs (mpirun stops every rank when one dies):\n");
  for (int r = 0; r < g_size && r < kMaxRanks; ++r) {
    const long j = g_held[r].job.load();
    const bool here = r == 0 || std::strcmp(g_held[r].host, g_host) == 0;
    const bool gone = r != 0 && here && g_held[r].pid > 0 && kill(pid_t(g_held[r].pid), 0) != 0 && errno == ESRCH;
    Put("  rank ");
    PutNum(r);
    if (r != 0) {
      Put(" (");
      Put(g_held[r].host);
      Put(", pid ");
      PutNum(g_held[r].pid);
      Put(")");
    }
    Put(gone ? ": died holding " : ": ");
    if (j >= 0)
      PutJob(j);
    else
      Put("no job");
    Put("\n");
  }
  Reraise(sig);
}

// A rank other than 0 killed by a fatal signal (or stopped): what it held.
void RankSignal(int sig) {
  Put("furnihost: rank ");
  PutNum(g_rank);
  Put(" (");
  Put(g_host);
  Put(", pid ");
  PutNum(long(getpid()));
  Put(") ended by signal ");
  PutNum(sig);
  const long j = g_held[0].job.load();
  Put(j >= 0 ? " while running " : " between jobs");
  if (j >= 0) PutJob(j);
  Put("\n");
  Reraise(sig);
}

// Installs the handler for the signals of a rank's role while jobs are shared; restores the
// previous ones after.
class SignalScope {
 public:
  SignalScope(bool root) {
    sigs_ = root ? std::vector<int>{SIGTERM, SIGINT, SIGHUP}
                 : std::vector<int>{SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGTERM, SIGINT, SIGHUP};
    struct sigaction sa {};
    sa.sa_handler = root ? RootStopped : RankSignal;
    sigemptyset(&sa.sa_mask);
    for (int s : sigs_) sigaction(s, &sa, &g_old[s]);
  }
  ~SignalScope() {
    for (int s : sigs_) sigaction(s, &g_old[s], nullptr);
  }

 private:
  std::vector<int> sigs_;
};

void CopyHost(char* dst, const std::string& src) { std::snprintf(dst, 64, "%s", src.c_str()); }

std::string Index(size_t i) {
  wire::Writer w;
  w.Pod(uint64_t(i));
  return w.Take();
}
std::string Code(int code) {
  wire::Writer w;
  w.Pod(int32_t(code));
  return w.Take();
}
int CodeOf(const std::string& bytes) {
  wire::Reader r(bytes, "MPI stop message");
  return r.Pod<int32_t>();
}

// ---- rank 0 --------------------------------------------------------------------------------
std::vector<std::string> Root(const World& world, size_t n, const std::function<std::string(size_t)>& run,
                              const std::vector<std::string>& jobs) {
  std::vector<std::string> results(n);
  std::mutex mu;
  size_t next = 0;
  bool failed = false;  // a job threw: hand out no more
  Kind fail_kind = Kind::kInternal;
  std::string fail_what;
  auto take = [&]() -> long {
    std::lock_guard<std::mutex> lock(mu);
    return failed || next >= n ? -1 : long(next++);
  };
  auto fail = [&](Kind k, const std::string& what) {
    std::lock_guard<std::mutex> lock(mu);
    if (!failed) failed = true, fail_kind = k, fail_what = what;
  };
  // The dispatcher: answers the other ranks until each has been told there is no more.
  std::exception_ptr dispatcher_error;
  std::thread dispatcher([&] {
    try {
      int open = world.Size() - 1;
      while (open > 0) {
        const auto m = world.Receive(true);
        const int r = m->source;
        wire::Reader in(m->bytes, "MPI message from rank " + std::to_string(r));
        if (m->tag == kReady) {
          g_held[r].pid = long(in.Pod<int64_t>());
          CopyHost(g_held[r].host, in.Str());
        } else if (m->tag == kResult) {
          const uint64_t j = in.Pod<uint64_t>();
          if (j >= n || long(j) != g_held[r].job.load()) throw std::runtime_error("rank " + std::to_string(r) + " returned a job it did not hold");
          std::string bytes = in.Str();
          std::lock_guard<std::mutex> lock(mu);
          results[j] = std::move(bytes);
        } else if (m->tag == kFailed) {
          const uint64_t j = in.Pod<uint64_t>();
          const Kind k = Kind(in.Pod<int32_t>());
          const std::string what = in.Str();
          fail(k, "rank " + std::to_string(r) + " (" + g_held[r].host + "): job " + std::to_string(j + 1) + " of " +
                      std::to_string(n) + " (" + (j < n ? jobs[j] : std::string("?")) + "): " + what);
        } else {
          throw std::runtime_error("unexpected message (tag " + std::to_string(m->tag) + ") from rank " + std::to_string(r));
        }
        g_held[r].job = -1;
        bool stop;
        {
          std::lock_guard<std::mutex> lock(mu);
          stop = failed;
        }
        if (stop) {
          world.Send(r, kStop, Code(ExitCode(fail_kind)));
          --open;
          continue;
        }
        const long j = take();
        if (j < 0) {
          world.Send(r, kDone, "");
          --open;
        } else {
          g_held[r].job = j;
          world.Send(r, kJob, Index(size_t(j)));
        }
      }
    } catch (...) {
      dispatcher_error = std::current_exception();
      fail(Kind::kInternal, "MPI: rank 0's dispatcher failed");
    }
  });
  // Rank 0's own share.
  std::exception_ptr own_error;
  for (long j; (j = take()) >= 0;) {
    g_held[0].job = j;
    try {
      std::string bytes = run(size_t(j));
      std::lock_guard<std::mutex> lock(mu);
      results[size_t(j)] = std::move(bytes);
    } catch (...) {
      own_error = std::current_exception();
      std::string what;
      const Kind k = KindOf(own_error, &what);
      fail(k, what);
    }
    g_held[0].job = -1;
  }
  dispatcher.join();
  if (own_error) std::rethrow_exception(own_error);
  if (dispatcher_error) std::rethrow_exception(dispatcher_error);
  if (failed) Throw(fail_kind, fail_what);
  return results;
}

// ---- the other ranks -------------------------------------------------------------------------
void Worker(const World& world, const std::function<std::string(size_t)>& run) {
  wire::Writer hello;
  hello.Pod(int64_t(getpid()));
  hello.Str(world.Host());
  world.Send(0, kReady, hello.Take());
  for (;;) {
    const auto m = world.Receive(true);
    if (m->source != 0) throw std::runtime_error("MPI: rank " + std::to_string(world.Rank()) +
                                                 ": unexpected message from rank " + std::to_string(m->source));
    if (m->tag == kDone) return;
    if (m->tag == kStop) throw RankStopped{CodeOf(m->bytes)};
    if (m->tag != kJob) throw std::runtime_error("MPI: unexpected message (tag " + std::to_string(m->tag) + ")");
    wire::Reader in(m->bytes, "MPI job message");
    const uint64_t j = in.Pod<uint64_t>();
    g_held[0].job = long(j);
    wire::Writer out;
    out.Pod(j);
    int tag = kResult;
    try {
      out.Str(run(size_t(j)));
    } catch (...) {
      std::string what;
      const Kind k = KindOf(std::current_exception(), &what);
      out = wire::Writer();
      out.Pod(j);
      out.Pod(int32_t(k));
      out.Str(what);
      tag = kFailed;
    }
    g_held[0].job = -1;
    world.Send(0, tag, out.Take());
  }
}

}  // namespace

std::vector<std::string> ShareJobs(const World& world, size_t n, const std::function<std::string(size_t)>& run,
                                   const std::function<std::string(size_t)>& describe) {
  if (!world.Shared()) {
    std::vector<std::string> results(n);
    for (size_t i = 0; i < n; ++i) results[i] = run(i);
    return results;
  }
  std::vector<std::string> jobs(n);
  for (size_t i = 0; i < n; ++i) jobs[i] = describe(i);
  g_jobs = &jobs;
  g_rank = world.Rank(), g_size = world.Size();
  CopyHost(g_host, world.Host());
  for (auto& h : g_held) h.job = -1;
  struct Reset {
    ~Reset() { g_jobs = nullptr; }
  } reset;
  const SignalScope signals(world.Root());
  if (world.Root()) return Root(world, n, run, jobs);
  Worker(world, run);
  return {};
}

std::string FromRoot(const World& world, const std::function<std::string()>& make) {
  if (!world.Shared()) return make();
  if (world.Root()) {
    std::string bytes;
    try {
      bytes = make();
    } catch (...) {
      std::string what;
      const int code = ExitCode(KindOf(std::current_exception(), &what));
      for (int r = 1; r < world.Size(); ++r) world.Send(r, kRootFailed, Code(code));
      throw;
    }
    for (int r = 1; r < world.Size(); ++r) world.Send(r, kRoot, bytes);
    return bytes;
  }
  const auto m = world.Receive(true);
  if (m->source != 0 || (m->tag != kRoot && m->tag != kRootFailed))
    throw std::runtime_error("MPI: rank " + std::to_string(world.Rank()) + ": unexpected message (tag " +
                             std::to_string(m->tag) + ") from rank " + std::to_string(m->source));
  if (m->tag == kRootFailed) throw RankStopped{CodeOf(m->bytes)};
  return std::move(m->bytes);
}

}  // namespace furnihost::app
