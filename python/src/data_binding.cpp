// Presets, systems, data generation and CSV files from Python. Generation goes through the
// same library calls as `csympnet generate`, so the same arguments give the same bits.
#include <optional>
#include <string>

#include <pybind11/stl.h>

#include "convert.hpp"
#include "csympnet/data/csv.hpp"
#include "csympnet/data/generate.hpp"
#include "csympnet/integrators/reference.hpp"
#include "csympnet/models/model.hpp"
#include "csympnet/paper/run.hpp"
#include "model_binding.hpp"

namespace csympnet::py_binding {

namespace {

py::tuple pairs_to(const PairSet& p) {
  return py::make_tuple(states_to(p.z0), states_to(p.z1), vector_to(p.h));
}

System system_from(const std::string& system_json) {
  return System(parse_json(system_json, "system").get<SystemSpec>());
}

// The preset's system with `overrides` (JSON object, or null) merged in, then validated.
SystemSpec merged_system(const Preset& p, const std::string& overrides_json) {
  const nlohmann::json overrides = parse_json(overrides_json, "system");
  nlohmann::json sys = p.system;
  if (!overrides.is_null()) {
    require(overrides.is_object(), "system: expected a dict of system fields");
    sys.update(overrides);
  }
  return sys.get<SystemSpec>();
}

struct GenerateArgs {
  std::string preset, split, reference, system_json;
  std::uint64_t seed;
  bool seed_given;
  std::optional<long> n;
  std::optional<std::pair<double, double>> h;
  double sigma;
};

// `csympnet generate` (apps/csympnet/cmd_data.cpp): one split of a preset's data. The test
// split uses data seed 0 unless a seed is given. Returns (z0, z1, h) for train/val, a list of
// (t, z) and the redraw count for test.
py::object generate(const GenerateArgs& a) {
  require(a.split == "train" || a.split == "val" || a.split == "test",
          [&] { return "split: expected 'train', 'val' or 'test', got '" + a.split + "'"; });
  RunConfig c = default_run_config(a.preset, "csympnet");
  c.preset.system = merged_system(c.preset, a.system_json);
  c.reference.method = parse_reference(a.reference);
  c.sigma = a.sigma;
  c.seed = a.seed;
  const bool test = a.split == "test";
  c.test_seed = a.seed_given ? a.seed : 0;
  if (a.n) {
    require(*a.n >= 1, [&] { return "n: expected an integer >= 1, got " + std::to_string(*a.n); });
    (test ? c.preset.n_test : (a.split == "train" ? c.preset.n_train : c.preset.n_val)) = *a.n;
  }
  if (a.h) c.preset.train_steps = {a.h->first, a.h->second};
  c.validate();
  RunData d;
  {
    py::gil_scoped_release nogil;
    d = generate_run_data(c);
  }
  if (test) return py::make_tuple(trajectories_to(d.test.trajectories), d.test.redraws);
  return pairs_to(a.split == "train" ? d.train : d.val);
}

}  // namespace

void bind_data(py::module_& m) {
  m.def("preset_names", &preset_names);
  m.def("model_types", &model_types);
  m.def(
      "preset_json",
      [](const std::string& name) { return nlohmann::json(preset_by_name(name)).dump(); },
      py::arg("name"));
  m.def(
      "generate",
      [](const std::string& preset, const std::string& split, std::uint64_t seed, bool seed_given,
         std::optional<long> n, std::optional<std::pair<double, double>> h, double sigma,
         const std::string& reference, const std::string& system_json) {
        return generate({preset, split, reference, system_json, seed, seed_given, n, h, sigma});
      },
      py::arg("preset"), py::arg("split"), py::arg("seed"), py::arg("seed_given"), py::arg("n"),
      py::arg("h"), py::arg("sigma"), py::arg("reference"), py::arg("system_json"));
  m.def(
      "test_set",
      [](const std::string& system_json, long n, double h_test, double horizon, std::uint64_t seed,
         const std::string& reference) {
        const System sys = system_from(system_json);
        ReferenceOptions ref;
        ref.method = parse_reference(reference);
        require(n >= 1, "n_test: expected an integer >= 1");
        TestSet t;
        {
          py::gil_scoped_release nogil;
          Rng rng(seed, "test-trajectories");
          t = generate_test_set(sys, n, h_test, horizon, rng, ref);
        }
        return py::make_tuple(trajectories_to(t.trajectories), t.redraws);
      },
      py::arg("system_json"), py::arg("n"), py::arg("h_test"), py::arg("horizon"), py::arg("seed"),
      py::arg("reference"),
      "generate_test_set() with the stream `csympnet evaluate --preset` uses.");
  m.def(
      "check_system",
      [](const std::string& system_json) {
        return nlohmann::json(system_from(system_json).spec()).dump();
      },
      py::arg("system_json"), "Validates a system spec; returns it with every field.");
  m.def(
      "energy",
      [](const std::string& system_json, const DArray& z) {
        const System sys = system_from(system_json);
        const Matrix zs = states_from(z, "z", sys.dim());
        Vector e(zs.cols());
        for (Index j = 0; j < zs.cols(); ++j) e(j) = sys.energy(zs.col(j));
        return vector_to(e);
      },
      py::arg("system_json"), py::arg("z"));
  m.def(
      "vector_field",
      [](const std::string& system_json, const DArray& z) {
        const System sys = system_from(system_json);
        const Matrix zs = states_from(z, "z", sys.dim());
        Matrix f(zs.rows(), zs.cols());
        for (Index j = 0; j < zs.cols(); ++j) f.col(j) = sys.vector_field(zs.col(j));
        return states_to(f);
      },
      py::arg("system_json"), py::arg("z"));
  m.def(
      "flow",
      [](const std::string& system_json, const DArray& z, const DArray& h,
         const std::string& reference) {
        const System sys = system_from(system_json);
        const Matrix zs = states_from(z, "z", sys.dim());
        const Vector hs = vector_from(h, "h", zs.cols());
        require((hs.array() > 0.0).all() && hs.allFinite(), "h: expected finite steps > 0");
        ReferenceOptions ref;
        ref.method = parse_reference(reference);
        Matrix out;
        {
          py::gil_scoped_release nogil;
          out = reference_flow(sys, zs, hs, ref);
        }
        return states_to(out);
      },
      py::arg("system_json"), py::arg("z"), py::arg("h"), py::arg("reference"));
  m.def(
      "pairs_from_trajectories",
      [](const py::sequence& trajs) {
        return pairs_to(pairs_from_trajectories(trajectories_from(trajs, "trajectories")));
      },
      py::arg("trajectories"));
  m.def(
      "read_csv",
      [](const std::string& path) -> py::tuple {
        if (detect_csv_kind(path) == CsvKind::kPairs)
          return py::make_tuple("pairs", pairs_to(read_pairs_csv(path)));
        return py::make_tuple("trajectories", trajectories_to(read_trajectories_csv(path)));
      },
      py::arg("path"));
  m.def(
      "write_pairs_csv",
      [](const std::string& path, const DArray& z0, const DArray& z1, const DArray& h) {
        PairSet p;
        p.z0 = states_from(z0, "z0");
        p.z1 = states_from(z1, "z1", p.z0.rows());
        p.h = vector_from(h, "h", p.z0.cols());
        write_pairs_csv(path, p);
      },
      py::arg("path"), py::arg("z0"), py::arg("z1"), py::arg("h"));
  m.def(
      "write_trajectories_csv",
      [](const std::string& path, const py::sequence& trajs) {
        write_trajectories_csv(path, trajectories_from(trajs, "trajectories"));
      },
      py::arg("path"), py::arg("trajectories"));
}

}  // namespace csympnet::py_binding
