// Standard output is checked as coreutils checks it: a write that fails (a full disk,
// `> /dev/full`, a closed stream `>&-`) is an error with exit 1, never a silent success.
#pragma once

#include <string>

namespace csympnet::cli {

// Makes sure file descriptors 0, 1 and 2 are open. One that was closed (`>&-`) is opened on
// /dev/null in the direction it cannot be used (standard output read-only), so writing to it
// still fails with EBADF instead of going into the next file the command opens (a lock file,
// a model file) that would otherwise get that descriptor.
void keep_standard_descriptors_taken();

// The message for a failed write to standard output with errno `err` (0: unknown).
std::string stdout_write_error(int err);

// Writes `line` and a newline to standard output; throws Error at once if the write fails.
void print_line(const std::string& line);

// Flushes standard output (std::cout and stdio). Returns `code` when every write succeeded;
// otherwise prints the write error and returns 1 if `code` was a success (0, or 4: not
// identified), else `code` (the first failure is the one reported).
int finish_standard_output(int code);

}  // namespace csympnet::cli
