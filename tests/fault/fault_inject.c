/* An LD_PRELOAD shim that makes one file operation of a process fail, or kills the process
 * there, for the fault-injection test (tests/cli/fault_injection_test.cpp; docs/hardening.md,
 * "Fault injection"), in the manner of SQLite's I/O-error tests.
 *
 * Counted operations: write() to a regular file other than standard input, output and error,
 * fsync(), and rename(). With CSYMPNET_FAULT_AT=N, the N-th counted operation (1-based) either
 * fails (CSYMPNET_FAULT_MODE=fail: write with ENOSPC, fsync with EIO, rename with EIO) or kills
 * the process with SIGKILL before it happens (CSYMPNET_FAULT_MODE=kill). CSYMPNET_FAULT_MARK,
 * when set, names a file created when the fault is injected, so the test knows that it was. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

static atomic_long counted;

/* 1: inject now (after marking); 0: go on. */
static int fault_now(void) {
  const char* at = getenv("CSYMPNET_FAULT_AT");
  if (at == NULL) return 0;
  const long n = atomic_fetch_add(&counted, 1) + 1;
  if (n != strtol(at, NULL, 10)) return 0;
  const char* mark = getenv("CSYMPNET_FAULT_MARK");
  if (mark != NULL) {
    const int fd = open(mark, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd >= 0) close(fd);
  }
  const char* mode = getenv("CSYMPNET_FAULT_MODE");
  if (mode != NULL && strcmp(mode, "kill") == 0) kill(getpid(), SIGKILL);
  return 1;
}

static int is_counted_fd(int fd) {
  struct stat st;
  return fd > 2 && fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
}

ssize_t write(int fd, const void* buf, size_t count) {
  static ssize_t (*real)(int, const void*, size_t);
  if (real == NULL) real = (ssize_t(*)(int, const void*, size_t))dlsym(RTLD_NEXT, "write");
  if (is_counted_fd(fd) && fault_now()) {
    errno = ENOSPC;
    return -1;
  }
  return real(fd, buf, count);
}

int fsync(int fd) {
  static int (*real)(int);
  if (real == NULL) real = (int (*)(int))dlsym(RTLD_NEXT, "fsync");
  if (is_counted_fd(fd) && fault_now()) {
    errno = EIO;
    return -1;
  }
  return real(fd);
}

int rename(const char* from, const char* to) {
  static int (*real)(const char*, const char*);
  if (real == NULL) real = (int (*)(const char*, const char*))dlsym(RTLD_NEXT, "rename");
  if (fault_now()) {
    errno = EIO;
    return -1;
  }
  return real(from, to);
}
