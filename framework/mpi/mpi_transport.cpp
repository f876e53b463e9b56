// libfurnihost_mpi: the MPI side of furnihost's job sharing (framework/app/mpi_world.cpp), in a
// library of its own that the app loads (dlopen, RTLD_GLOBAL: Open MPI's components resolve the
// MPI symbols through the global scope) only when a launcher (mpirun, srun) started the process
// as one of several ranks. A command outside mpirun, and every build without MPI, never loads
// libmpi.
//
// The interface is C and bytes only: each rank opens the world (MPI_Init_thread, at least
// MPI_THREAD_SERIALIZED: rank 0's dispatcher thread and its main thread call MPI one at a time),
// sends and receives byte messages with a tag, polls for a message, aborts, closes. Errors come
// back as return codes (MPI_ERRORS_RETURN), with the library's message.
#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>

#define FURNIHOST_MPI_EXPORT __attribute__((visibility("default")))

namespace {
// Messages travel in chunks of at most this many bytes (MPI counts are ints).
constexpr size_t kChunk = size_t(1) << 30;

void ErrorText(int code, char* err, size_t len) {
  if (!err || len == 0) return;
  char text[MPI_MAX_ERROR_STRING];
  int n = 0;
  if (MPI_Error_string(code, text, &n) != MPI_SUCCESS) n = std::snprintf(text, sizeof text, "MPI error %d", code);
  std::snprintf(err, len, "%.*s", n, text);
}
}  // namespace

extern "C" {

// Opens the world; rank, size and this host's name. 0 on success, else an MPI error code and
// its text in err.
FURNIHOST_MPI_EXPORT int furnihost_mpi_init(int* rank, int* size, char* host, size_t host_len, char* err, size_t err_len) {
  // Open MPI's default point-to-point layer probes UCX at start-up, ~0.2 s of every rank on a
  // workstation; furnihost's messages are few and small (a job index, a result), which the ob1
  // layer (shared memory on a node, TCP between nodes) carries as fast. A pml the user chose
  // (OMPI_MCA_pml, mpirun --mca pml ...) stays; other MPI libraries ignore the variable.
  setenv("OMPI_MCA_pml", "ob1", 0);
  int provided = 0;
  int rc = MPI_Init_thread(nullptr, nullptr, MPI_THREAD_SERIALIZED, &provided);
  if (rc != MPI_SUCCESS) return ErrorText(rc, err, err_len), rc;
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  if (provided < MPI_THREAD_SERIALIZED) {
    std::snprintf(err, err_len, "the MPI library gives thread level %d, furnihost needs MPI_THREAD_SERIALIZED", provided);
    return -1;
  }
  if ((rc = MPI_Comm_rank(MPI_COMM_WORLD, rank)) != MPI_SUCCESS || (rc = MPI_Comm_size(MPI_COMM_WORLD, size)) != MPI_SUCCESS)
    return ErrorText(rc, err, err_len), rc;
  char name[MPI_MAX_PROCESSOR_NAME];
  int n = 0;
  if (MPI_Get_processor_name(name, &n) != MPI_SUCCESS) n = 0;
  std::snprintf(host, host_len, "%.*s", n, name);
  return 0;
}

// Sends n bytes to rank `dest` with `tag` (the length first, then the chunks).
FURNIHOST_MPI_EXPORT int furnihost_mpi_send(int dest, int tag, const void* data, size_t n, char* err, size_t err_len) {
  uint64_t len = n;
  int rc = MPI_Send(&len, 1, MPI_UINT64_T, dest, tag, MPI_COMM_WORLD);
  for (size_t at = 0; rc == MPI_SUCCESS && at < n; at += kChunk) {
    const size_t part = n - at < kChunk ? n - at : kChunk;
    rc = MPI_Send(static_cast<const char*>(data) + at, int(part), MPI_BYTE, dest, tag, MPI_COMM_WORLD);
  }
  if (rc != MPI_SUCCESS) ErrorText(rc, err, err_len);
  return rc;
}

// Whether a message is waiting (any rank, any tag): 1 with its source, tag and length, 0 when
// none (block = 0), -1 on an error (its text in err). With block != 0 it waits for one.
FURNIHOST_MPI_EXPORT int furnihost_mpi_poll(int block, int* source, int* tag, uint64_t* len, char* err, size_t err_len) {
  MPI_Status st;
  int flag = 1;
  int rc = block ? MPI_Probe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &st)
                 : MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &st);
  if (rc != MPI_SUCCESS) return ErrorText(rc, err, err_len), -1;
  if (!flag) return 0;
  *source = st.MPI_SOURCE;
  *tag = st.MPI_TAG;
  rc = MPI_Recv(len, 1, MPI_UINT64_T, st.MPI_SOURCE, st.MPI_TAG, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  if (rc != MPI_SUCCESS) return ErrorText(rc, err, err_len), -1;
  return 1;
}

// The body (len bytes, after furnihost_mpi_poll gave its length) of the message from `source`
// with `tag`.
FURNIHOST_MPI_EXPORT int furnihost_mpi_recv(int source, int tag, void* data, uint64_t len, char* err, size_t err_len) {
  int rc = MPI_SUCCESS;
  for (uint64_t at = 0; rc == MPI_SUCCESS && at < len; at += kChunk) {
    const uint64_t part = len - at < kChunk ? len - at : kChunk;
    rc = MPI_Recv(static_cast<char*>(data) + at, int(part), MPI_BYTE, source, tag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  }
  if (rc != MPI_SUCCESS) ErrorText(rc, err, err_len);
  return rc;
}

FURNIHOST_MPI_EXPORT void furnihost_mpi_abort(int code) { MPI_Abort(MPI_COMM_WORLD, code); }

FURNIHOST_MPI_EXPORT void furnihost_mpi_finalize() {
  int done = 0;
  MPI_Finalized(&done);
  if (!done) MPI_Finalize();
}

}  // extern "C"
