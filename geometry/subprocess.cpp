// posix_spawn-based process start (see subprocess.h for why not fork).

#include "geometry/subprocess.h"

#include "geometry/errors.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

extern char** environ;

namespace fascicle {

namespace {

const char kParentVariable[] = "FASCICLE_PARENT_PID";

// posix_spawn's attribute and file-action objects, released on every path.
struct SpawnState {
  posix_spawn_file_actions_t actions;
  posix_spawnattr_t attributes;
  SpawnState() {
    posix_spawn_file_actions_init(&actions);
    posix_spawnattr_init(&attributes);
  }
  ~SpawnState() {
    posix_spawn_file_actions_destroy(&actions);
    posix_spawnattr_destroy(&attributes);
  }
  SpawnState(const SpawnState&) = delete;
  SpawnState& operator=(const SpawnState&) = delete;
};

}  // namespace

pid_t spawn_process(const SpawnOptions& options) {
  if (options.argv.empty()) throw OptionError("spawn: argv must name a program");
  const std::string& program = options.argv.front();
  if (::access(program.c_str(), X_OK) != 0)
    throw Error(ErrorCode::file_missing, program + ": cannot run it (" + std::strerror(errno) + ")");

  SpawnState state;
  if (!options.log_file.empty()) {
    posix_spawn_file_actions_addopen(&state.actions, STDOUT_FILENO, options.log_file.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&state.actions, STDOUT_FILENO, STDERR_FILENO);
  } else if (options.stdout_fd >= 0) {
    posix_spawn_file_actions_adddup2(&state.actions, options.stdout_fd, STDOUT_FILENO);
  }
  if (options.stdin_fd >= 0) posix_spawn_file_actions_adddup2(&state.actions, options.stdin_fd, STDIN_FILENO);
  if (options.silence_stderr && options.log_file.empty())
    posix_spawn_file_actions_addopen(&state.actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  // The child starts with default signal handlers and an empty signal mask, whatever this
  // process (or the thread calling) has set up.
  sigset_t all, none;
  sigfillset(&all);
  sigemptyset(&none);
  posix_spawnattr_setsigdefault(&state.attributes, &all);
  posix_spawnattr_setsigmask(&state.attributes, &none);
  posix_spawnattr_setflags(&state.attributes, POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK);

  std::vector<char*> argv;
  for (const std::string& a : options.argv) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  // The environment, less any FASCICLE_PARENT_PID inherited from our own parent, plus ours.
  std::vector<std::string> own;
  std::vector<char*> envp;
  const std::size_t name_length = sizeof(kParentVariable) - 1;
  for (char** e = environ; e && *e; ++e)
    if (std::strncmp(*e, kParentVariable, name_length) != 0 || (*e)[name_length] != '=') envp.push_back(*e);
  if (options.die_with_parent) {
    own.push_back(std::string(kParentVariable) + "=" + std::to_string(::getpid()));
    envp.push_back(own.back().data());
  }
  envp.push_back(nullptr);

  pid_t pid = -1;
  const int error = posix_spawn(&pid, program.c_str(), &state.actions, &state.attributes, argv.data(), envp.data());
  if (error != 0)
    throw Error(error == ENOENT || error == EACCES ? ErrorCode::file_missing : ErrorCode::internal,
                program + ": cannot start it (" + std::strerror(error) + ")");
  return pid;
}

int wait_process(pid_t pid) {
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return -1;
  }
  return status;
}

std::string describe_wait_status(int status) {
  if (status == -1) return "could not be waited for";
  if (WIFEXITED(status)) return "exited with status " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) {
    const char* name = ::strsignal(WTERMSIG(status));
    return "was killed by signal " + std::to_string(WTERMSIG(status)) + (name ? std::string(" (") + name + ")" : "");
  }
  return "ended with wait status " + std::to_string(status);
}

void die_with_parent_if_asked() {
  const char* value = std::getenv(kParentVariable);
  if (value == nullptr || *value == '\0') return;
  char* end = nullptr;
  const long parent = std::strtol(value, &end, 10);
  if (end == value || *end != '\0' || parent <= 0) return;
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);
  // The parent may have died before the request took effect: then we were re-parented.
  if (::getppid() != static_cast<pid_t>(parent)) std::_Exit(1);
}

}  // namespace fascicle
