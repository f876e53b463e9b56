#include "mpi_world.hpp"

#include <dlfcn.h>

#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <thread>

#include "furnihost/error.hpp"
#include "furnihost/log.hpp"

namespace furnihost::app {

namespace {

int EnvInt(const char* name, int fallback) {
  const char* v = std::getenv(name);
  if (!v || !*v) return fallback;
  char* end = nullptr;
  const long x = std::strtol(v, &end, 10);
  return end && *end == '\0' && x >= 0 && x < (1L << 30) ? int(x) : fallback;
}

// libfurnihost_mpi's functions (framework/mpi/mpi_transport.cpp).
struct Transport {
  int (*init)(int*, int*, char*, size_t, char*, size_t) = nullptr;
  int (*send)(int, int, const void*, size_t, char*, size_t) = nullptr;
  int (*poll)(int, int*, int*, uint64_t*, char*, size_t) = nullptr;
  int (*recv)(int, int, void*, uint64_t, char*, size_t) = nullptr;
  void (*finalize)() = nullptr;
};

Transport& Mpi() {
  static Transport t;
  return t;
}

// Loads libfurnihost_mpi.so (beside the binary's libraries: its RUNPATH); "" on success, else why not.
std::string LoadTransport() {
  // RTLD_GLOBAL: Open MPI's components, loaded by libmpi in turn, resolve libmpi's symbols
  // through the global scope. Never closed: MPI stays for the process.
  void* lib = dlopen("libfurnihost_mpi.so", RTLD_NOW | RTLD_GLOBAL);
  if (!lib) {
    const char* e = dlerror();
    return e ? e : "libfurnihost_mpi.so not found";
  }
  Transport& t = Mpi();
  t.init = reinterpret_cast<decltype(t.init)>(dlsym(lib, "furnihost_mpi_init"));
  t.send = reinterpret_cast<decltype(t.send)>(dlsym(lib, "furnihost_mpi_send"));
  t.poll = reinterpret_cast<decltype(t.poll)>(dlsym(lib, "furnihost_mpi_poll"));
  t.recv = reinterpret_cast<decltype(t.recv)>(dlsym(lib, "furnihost_mpi_recv"));
  t.finalize = reinterpret_cast<decltype(t.finalize)>(dlsym(lib, "furnihost_mpi_finalize"));
  if (!t.init || !t.send || !t.poll || !t.recv || !t.finalize) return "libfurnihost_mpi.so lacks a function";
  return "";
}

World* g_opened = nullptr;

}  // namespace

Launch LaunchFromEnvironment() {
  Launch l;
  if (std::getenv("OMPI_COMM_WORLD_SIZE")) {
    l.size = EnvInt("OMPI_COMM_WORLD_SIZE", 1), l.rank = EnvInt("OMPI_COMM_WORLD_RANK", 0), l.launcher = "mpirun";
  } else if (std::getenv("PMI_SIZE")) {
    l.size = EnvInt("PMI_SIZE", 1), l.rank = EnvInt("PMI_RANK", 0), l.launcher = "pmi";
  } else if (std::getenv("PMIX_RANK") && std::getenv("SLURM_NTASKS")) {
    l.size = EnvInt("SLURM_NTASKS", 1), l.rank = EnvInt("PMIX_RANK", 0), l.launcher = "slurm";
  }
  if (l.size < 1 || l.rank >= l.size) l = Launch();
  return l;
}

World& World::Get() {
  static World* world = [] {
    auto* w = new World();  // lives until the process exits (Close ends MPI)
    const Launch l = LaunchFromEnvironment();
    if (l.size <= 1) return w;
    const std::string why = LoadTransport();
    if (!why.empty()) {
      // Built without MPI (or its library moved): one process does the work.
      if (l.rank == 0)
        spdlog::warn("launched as rank 0 of {} ({}), but this furnihost has no MPI ({}): rank 0 runs the whole "
                     "command alone; build with MPI (libopenmpi-dev) to share it",
                     l.size, l.launcher, why);
      w->rank_ = l.rank;
      w->size_ = 1;
      return w;
    }
    char host[256] = "", err[512] = "";
    int rank = 0, size = 1;
    if (Mpi().init(&rank, &size, host, sizeof host, err, sizeof err) != 0)
      throw InputError(std::string("MPI: cannot initialise (") + err + ")");
    w->rank_ = rank, w->size_ = size, w->host_ = host, w->mpi_ = true;
    g_opened = w;
    spdlog::debug("MPI: rank {} of {} on {}", rank, size, host);
    return w;
  }();
  if (!world->mpi_ && world->rank_ != 0) throw RankStopped{0};  // a rank of a run without MPI: rank 0 works alone
  return *world;
}

bool RunsOnThisRank(const std::string& command) {
  const Launch l = LaunchFromEnvironment();
  if (l.size <= 1 || l.rank == 0) return true;
  spdlog::debug("furnihost {}: rank {} of {}: the command runs on rank 0 alone", command, l.rank, l.size);
  return false;
}

void World::Send(int dest, int tag, const std::string& bytes) const {
  char err[512] = "";
  if (Mpi().send(dest, tag, bytes.data(), bytes.size(), err, sizeof err) != 0)
    throw StageError(std::string("MPI: rank ") + std::to_string(rank_) + " cannot send to rank " + std::to_string(dest) +
                         " (" + err + ")",
                     false);
}

std::optional<World::Message> World::Receive(bool wait) const {
  char err[512] = "";
  auto sleep_for = std::chrono::microseconds(50);
  for (;;) {
    Message m;
    uint64_t len = 0;
    const int got = Mpi().poll(0, &m.source, &m.tag, &len, err, sizeof err);
    if (got < 0) throw StageError(std::string("MPI: rank ") + std::to_string(rank_) + " cannot receive (" + err + ")", false);
    if (got == 1) {
      m.bytes.resize(len);
      if (Mpi().recv(m.source, m.tag, m.bytes.data(), len, err, sizeof err) != 0)
        throw StageError(std::string("MPI: rank ") + std::to_string(rank_) + " cannot receive from rank " +
                             std::to_string(m.source) + " (" + err + ")",
                         false);
      return m;
    }
    if (!wait) return std::nullopt;
    // MPI's blocking receive spins on its core; a rank waiting here (for rank 0 to train a
    // model, say) sleeps instead, up to 2 ms between polls.
    std::this_thread::sleep_for(sleep_for);
    sleep_for = std::min(sleep_for * 2, std::chrono::microseconds(2000));
  }
}

void World::Close() {
  if (g_opened) {
    Mpi().finalize();
    g_opened = nullptr;
  }
}

}  // namespace furnihost::app
