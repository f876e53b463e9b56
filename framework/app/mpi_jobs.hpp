// Work shared among the ranks of a World (mpi_world.hpp): the (scene, seed, config) jobs of
// `furnihost eval`, the catalog models of a training.
//
// ShareJobs hands jobs out as ranks ask for them (rank 0 works too; a thread of rank 0 answers
// the others), and rank 0 gets every job's result back in job order: a job's result is the
// same bytes whichever rank ran it (a job depends on its inputs only), so rank 0 then writes
// what one process writes. FromRoot hands every rank what rank 0 made (a model it loaded or
// trained). In a world of one rank both simply run here.
//
// Failures: a job that throws on any rank ends the run: the rank says so to rank 0, rank 0
// stops handing out jobs, tells every rank to stop once its job is done, and throws the error
// naming the rank, its host and the job (exit code of the error's kind); the other ranks exit
// with that code quietly (RankStopped). A rank that dies (a signal, the OOM killer) cannot say
// so: it prints what it held if it can (a fatal signal), and mpirun then stops every rank; rank
// 0 prints, as it is stopped, which job each rank held and which ranks on its host are gone.
// Nothing is written before every job is back, so a failed run leaves no output behind.
#pragma once
#include <functional>
#include <string>
#include <vector>

#include "mpi_world.hpp"

namespace furnihost::app {

// Jobs 0 .. n-1: run(i) computes job i's result bytes on whichever rank takes it; describe(i)
// names it in errors ("scene0003_00.ply, seed 42, config scannet"). Returns on rank 0 every
// result in job order, on the other ranks nothing.
std::vector<std::string> ShareJobs(const World& world, size_t n, const std::function<std::string(size_t)>& run,
                                   const std::function<std::string(size_t)>& describe);

// make() on rank 0, its bytes on every rank. When make throws, rank 0 tells the others (which
// throw RankStopped) and rethrows.
std::string FromRoot(const World& world, const std::function<std::string()>& make);

}  // namespace furnihost::app
