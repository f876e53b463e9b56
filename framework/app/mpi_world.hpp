// The processes of one command: this process alone, or the ranks an MPI launcher started
// (`mpirun -n N furnihost eval|train ...`, or srun in a Slurm job: docs/cluster.md).
//
// A launcher is recognised by its environment (Open MPI's OMPI_COMM_WORLD_SIZE, PMI's
// PMI_SIZE, PMIx's PMIX_RANK with Slurm's SLURM_NTASKS). Only then, and only for the commands
// that share work (eval, train), the world is opened: libfurnihost_mpi.so, the library built
// with MPI beside the host library, is loaded (dlopen) and initialises MPI. A furnihost built
// without MPI has no such library: launched as several ranks, rank 0 runs the command alone
// (with a warning) and the other ranks exit at once; outside a launcher nothing of MPI is
// loaded.
#pragma once
#include <optional>
#include <string>

namespace furnihost::app {

// What the launcher's environment says about this process (rank 0 of 1 outside a launcher).
struct Launch {
  int rank = 0, size = 1;
  std::string launcher;  // "mpirun", "pmi", "slurm" or "" (none)
};
Launch LaunchFromEnvironment();

class World {
 public:
  // This process's world: opened on the first call (MPI_Init when launched as several ranks
  // and built with MPI; else one rank). Throws InputError when MPI cannot be initialised.
  static World& Get();
  int Rank() const { return rank_; }
  int Size() const { return size_; }
  bool Root() const { return rank_ == 0; }
  bool Shared() const { return size_ > 1; }
  const std::string& Host() const { return host_; }

  // Byte messages between ranks with a tag (>= 0). Throws StageError (internal) when MPI
  // reports an error.
  void Send(int dest, int tag, const std::string& bytes) const;
  struct Message {
    int source = -1, tag = -1;
    std::string bytes;
  };
  // A waiting message from any rank, or none; with `wait`, the next one (polled, sleeping a
  // little between polls, so a waiting rank leaves its core to the others).
  std::optional<Message> Receive(bool wait) const;

  // Ends the MPI world before the process exits (every rank must; main calls it). Idempotent,
  // and nothing when the world was never opened.
  static void Close();

 private:
  World() = default;
  int rank_ = 0, size_ = 1;
  std::string host_;
  bool mpi_ = false;
};

// The commands that share work among ranks call World::Get(); every other command, launched as
// several ranks, runs on rank 0 alone: this returns false on the other ranks (after a note at
// debug level), which then exit with 0.
bool RunsOnThisRank(const std::string& command);

// Thrown on a rank that stops because another rank failed and said why (rank 0 prints the
// error): main exits with `code` without printing anything more.
struct RankStopped {
  int code = 1;
};

}  // namespace furnihost::app
