// Small file utilities: whole-file reads, crash-safe writes, and output-directory checks.
#pragma once

#include <string>

namespace csympnet {

// Returns the bytes of the file unchanged. Throws Error naming the path if it does not
// exist, is a directory, or cannot be read.
std::string read_text_file(const std::string& path);

// Writes `content` to a temporary file in the target's directory, flushes it to disk (fsync)
// and renames it over `path`, so readers see either the old file or the complete new one,
// never a half-written file. On failure the temporary is removed and Error names the path.
void write_text_atomic(const std::string& path, const std::string& content);

// Makes `dir` (and missing parents) ready to receive results. An existing non-empty
// directory is refused unless `force`, so a run never silently overwrites an earlier one;
// an existing non-directory at `dir` is always refused.
void prepare_output_dir(const std::string& dir, bool force);

}  // namespace csympnet
