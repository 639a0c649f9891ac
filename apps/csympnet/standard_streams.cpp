#include "standard_streams.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <iostream>

#include "csympnet/core/error.hpp"

namespace csympnet::cli {

void keep_standard_descriptors_taken() {
  for (int fd = 0; fd <= 2; ++fd) {
    if (::fcntl(fd, F_GETFD) != -1 || errno != EBADF) continue;
    // open() returns the lowest free descriptor: this one.
    const int got = ::open("/dev/null", fd == 0 ? O_WRONLY : O_RDONLY);
    if (got >= 0 && got != fd) {
      ::dup2(got, fd);
      ::close(got);
    }
  }
}

std::string stdout_write_error(int err) {
  // The system's own reason, as coreutils give it ("write error: Broken pipe", "No space
  // left on device"); a guess at the cause would be wrong for all but one of them.
  return std::string("write error on standard output: ") +
         (err != 0 ? std::string(std::strerror(err))
                   : std::string("the system gave no reason (the stream is in error)")) +
         "; expected standard output to stay writable to the end";
}

void print_line(const std::string& line) {
  errno = 0;
  if (std::fputs(line.c_str(), stdout) < 0 || std::fputc('\n', stdout) == EOF)
    throw Error(stdout_write_error(errno));
}

int finish_standard_output(int code) {
  // std::cout writes through stdio (synchronised): its flush is stdio's, and the first flush
  // that fails is the one whose errno says why (a second finds nothing left to write).
  errno = 0;
  std::cout.flush();
  int err = std::cout.fail() ? errno : 0;
  errno = 0;
  const bool flush_failed = std::fflush(stdout) != 0;
  if (flush_failed && errno != 0) err = errno;
  if (!flush_failed && !std::ferror(stdout) && !std::cout.fail()) return code;
  if (code != 0 && code != 4) return code;
  std::fprintf(stderr, "csympnet: error: %s\n", stdout_write_error(err).c_str());
  return 1;
}

}  // namespace csympnet::cli
