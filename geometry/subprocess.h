#pragma once
/// \file subprocess.h
/// Starting helper programs from a process that may already run threads (TBB, a batch's
/// workers). fork() there leaves the child with only async-signal-safe calls allowed: the
/// dynamic loader, malloc or a lock another thread held at the fork can deadlock or abort it.
/// spawn_process() uses posix_spawn (glibc: clone with CLONE_VM | CLONE_VFORK, then exec), so the
/// child runs nothing of this process's code before the new program starts.

#include <string>
#include <sys/types.h>
#include <vector>

namespace fascicle {

/// How spawn_process() starts a program.
struct SpawnOptions {
  /// The program (a path; no PATH search) and its arguments. Required: must not be empty.
  std::vector<std::string> argv;
  /// Descriptor that becomes the child's standard input (default -1: inherited).
  int stdin_fd = -1;
  /// Descriptor that becomes the child's standard output (default -1: inherited).
  int stdout_fd = -1;
  /// When not empty, the child's standard output and standard error go to this file, created or
  /// truncated (default empty: inherited, or stdout_fd). Takes precedence over stdout_fd.
  std::string log_file;
  /// Send the child's standard error to /dev/null (default false).
  bool silence_stderr = false;
  /// The child is killed (SIGKILL) when the thread that spawned it ends, so that an interrupted
  /// parent leaves no worker running (default true). Works through the environment variable
  /// FASCICLE_PARENT_PID, which the child program must honour by calling
  /// die_with_parent_if_asked() first thing in main().
  bool die_with_parent = true;
};

/// Starts a program as described; returns its process id. Throws Error(file_missing) when the
/// program does not exist or is not executable, Error(internal) when the spawn itself fails;
/// the message is one line naming the program.
pid_t spawn_process(const SpawnOptions& options);

/// Waits for process `pid` (retrying on EINTR) and returns its wait status (see waitpid), or -1
/// when it cannot be waited for.
int wait_process(pid_t pid);

/// Describes a wait status in words: "exited with status 3", "was killed by signal 9 (Killed)".
std::string describe_wait_status(int status);

/// For programs that spawn_process() starts: when FASCICLE_PARENT_PID names the parent, asks the
/// kernel for SIGKILL when the parent dies (prctl PR_SET_PDEATHSIG) and exits at once with
/// status 1 when the parent is already gone. Does nothing when the variable is not set.
void die_with_parent_if_asked();

}  // namespace fascicle
