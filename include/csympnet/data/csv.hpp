// CSV input and output of snapshot data.
//
//   pairs:        h,q1..qd,p1..pd,next_q1..next_qd,next_p1..next_pd
//   trajectories: [traj,]t,q1..qd,p1..pd[,u1..um]   (traj optional: absent means one
//                                                    trajectory)
//   positions:    [traj,]t,q1..qd[,u1..um]          (no momenta: for csympnet fit, whose fit
//                                                    treats them as hidden states)
//
// u1..um are known inputs (models/inputs.hpp), sampled at the rows' times; a pairs file has none.
//
// Readers reject bad input with csympnet::Error naming the file, the line (and column where
// it applies), and what was expected. They never crash and never return partial data.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "csympnet/data/dataset.hpp"

namespace csympnet {

enum class CsvKind { kPairs, kTrajectories, kPositions };

// Inspects the header line only.
CsvKind detect_csv_kind(const std::string& path);

PairSet read_pairs_csv(const std::string& path);
std::vector<Trajectory> read_trajectories_csv(const std::string& path);
// Either format; trajectories become pairs of consecutive rows. For training: states and
// steps beyond 1e150 in magnitude (whose squares overflow) are refused at their line.
PairSet read_any_as_pairs(const std::string& path);

// The same readers on text already in memory (the fuzz targets use these); `name` stands for
// the path in messages.
PairSet parse_pairs_csv(std::string text, const std::string& name);
// Whether a trajectories or positions reader takes known inputs (columns u1..um): kRefuse, the
// default, refuses them at the header, naming the file and what reads them, since its consumer
// would drop them; kRead reads them into Trajectory::u (each value finite, at its line).
enum class InputColumns { kRefuse, kRead };
std::vector<Trajectory> parse_trajectories_csv(std::string text, const std::string& name,
                                               InputColumns inputs = InputColumns::kRefuse);
// A positions file: trajectories whose z holds the d position rows alone (d × n).
std::vector<Trajectory> parse_positions_csv(std::string text, const std::string& name,
                                            InputColumns inputs = InputColumns::kRefuse);
PairSet parse_any_as_pairs(std::string text, const std::string& name);

// An input read once, so that a pipe, a FIFO or "-" (standard input) works: its name for
// messages ("standard input" for "-"), its bytes and its kind (from the header line).
struct CsvInput {
  std::string name;
  std::string text;
  CsvKind kind = CsvKind::kPairs;
  Index inputs = 0;  // its input columns u1..um (from the header line)
};
CsvInput read_csv_input(const std::string& path);

// A file's own column names for the columns csympnet reads: pairs of (canonical name, the
// file's name), e.g. {"t", "time_s"}, {"q1", "angle_deg"}, {"p1", "velocity"}. The canonical
// names are traj, t, h, q1..qd, p1..pd, next_q1..next_qd, next_p1..next_pd and u1..um.
struct ColumnMap {
  std::vector<std::pair<std::string, std::string>> columns;
  bool empty() const { return columns.empty(); }
};
// Reads "t=time_s,q1=angle_deg,p1=velocity" (the CLI's --columns); refuses an unknown canonical
// name, a name given twice, or a malformed entry with an Error naming `option`.
ColumnMap parse_column_map(const std::string& spec, const std::string& option = "--columns");
// The CSV text with the map applied: each mapped column renamed to its canonical name, every
// column put in the canonical order, and columns neither mapped nor canonical dropped. Lines
// keep their numbers, so later messages still point into the user's file. Refuses, naming the
// file and line, a mapped name absent from the header or present twice, and a data line with
// another number of fields than the header. An empty map returns the text unchanged.
std::string apply_column_map(std::string text, const std::string& name, const ColumnMap& map);
// read_csv_input with the map applied (its kind detected from the rewritten header).
CsvInput read_csv_input(const std::string& path, const ColumnMap& map);

// Values are written as the shortest text that reads back to the same double (round_trip_text),
// so they read back bit-identical.
void write_pairs_csv(const std::string& path, const PairSet& pairs);
void write_trajectories_csv(const std::string& path, const std::vector<Trajectory>& trajs);
// The text the writers write (after the same validation).
std::string pairs_csv_text(const PairSet& pairs);
std::string trajectories_csv_text(const std::vector<Trajectory>& trajs);

}  // namespace csympnet
