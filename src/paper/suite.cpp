#include "csympnet/paper/suite.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <set>

#include "csympnet/core/error.hpp"
#include "csympnet/core/hash.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/io/json_text.hpp"
#include "csympnet/models/model.hpp"

namespace csympnet {

namespace {

using nlohmann::json;

// Bounds on what a suite file may ask for, checked before any run is expanded or trained.
constexpr std::int64_t kMaxSuiteNTrain = 10000000;
constexpr double kMaxSuiteRuns = 10000.0;

void reject_unknown_keys(const json& doc, const std::string& where,
                         const std::vector<std::string>& allowed) {
  for (const auto& item : doc.items()) {
    bool known = false;
    for (const auto& a : allowed) known = known || a == item.key();
    require(known, [&] {
      return where + ": unknown key '" + item.key() + "'; expected only the keys " +
             comma_separated(allowed);
    });
  }
}

// A list whose entries make runs (presets, models, seeds, sigmas, sizes) names each once: a
// repeat would be the same run twice, under one cache key.
template <class T>
void reject_repeats(const std::vector<T>& items, const std::string& where, const std::string& key) {
  for (std::size_t i = 0; i < items.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      require(!(items[i] == items[j]), [&] {
        return where + ": key '" + key + "' lists " + json(items[i]).dump() +
               " twice; expected each entry at most once";
      });
}

std::vector<std::string> string_list(const json& doc, const char* key, const std::string& where,
                                     const std::vector<std::string>& valid) {
  require(doc.contains(key), [&] {
    return where + ": missing key '" + key + "' (expected a list of: " + comma_separated(valid) +
           ")";
  });
  const json& v = doc.at(key);
  require(v.is_array() && !v.empty(), [&] {
    return where + ": key '" + key + "' = " + v.dump() + ", expected a non-empty list";
  });
  std::vector<std::string> out;
  for (const auto& item : v) {
    require(item.is_string(), [&] {
      return where + ": key '" + key + "' holds " + item.dump() +
             ", expected strings (one of: " + comma_separated(valid) + ")";
    });
    const auto s = item.get<std::string>();
    bool ok = false;
    for (const auto& name : valid) ok = ok || name == s;
    require(ok, [&] {
      return where + ": key '" + key + "' holds '" + s +
             "', expected one of: " + comma_separated(valid);
    });
    out.push_back(s);
  }
  reject_repeats(out, where, key);
  return out;
}

std::vector<double> number_list(const json& v, const std::string& where, const std::string& key,
                                double lo, bool lo_open) {
  require(v.is_array() && !v.empty(), [&] {
    return where + ": key '" + key + "' = " + v.dump() + ", expected a non-empty list of numbers";
  });
  std::vector<double> out;
  for (const auto& item : v) {
    require(item.is_number(), [&] {
      return where + ": key '" + key + "' holds " + item.dump() + ", expected numbers";
    });
    const double x = item.get<double>();
    require(std::isfinite(x) && (lo_open ? x > lo : x >= lo), [&] {
      return where + ": key '" + key + "' holds " + item.dump() + ", expected finite numbers " +
             (lo_open ? "> " : ">= ") + std::to_string(lo);
    });
    out.push_back(x);
  }
  reject_repeats(out, where, key);
  return out;
}

std::string reference_for(const SuiteSpec& s, const std::string& preset) {
  if (s.reference.is_null()) return "splitting";
  if (s.reference.is_string()) return s.reference.get<std::string>();
  return s.reference.contains(preset) ? s.reference.at(preset).get<std::string>() : "splitting";
}

std::vector<Index> n_train_for(const SuiteSpec& s, const Preset& p) {
  if (s.n_train.is_null() || !s.n_train.contains(p.name)) return {p.n_train};
  std::vector<Index> out;
  for (const auto& v : s.n_train.at(p.name)) out.push_back(v.get<Index>());
  return out;
}

// A short readable number for keys: 0.001 → "0.001", 1e-4 → "0.0001".
std::string compact(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}

// The optional per-preset run settings of a suite: n_train, reference, epochs.
void parse_run_options(const json& doc, const std::string& where, SuiteSpec& s) {
  if (doc.contains("n_train")) {
    s.n_train = doc.at("n_train");
    require(s.n_train.is_object(), [&] {
      return where + ": key 'n_train' = " + s.n_train.dump() +
             ", expected {\"preset\": [sizes], ...}";
    });
    for (const auto& item : s.n_train.items()) {  // clang 14 cannot capture bindings
      const std::string& preset = item.key();
      const json& sizes = item.value();
      preset_by_name(preset);
      require(sizes.is_array() && !sizes.empty(), [&] {
        return where + ": n_train." + preset + " = " + sizes.dump() + ", expected a list";
      });
      std::vector<std::int64_t> ns;
      for (const auto& n : sizes) {
        require(n.is_number_integer() && n.get<std::int64_t>() >= 4 &&
                    n.get<std::int64_t>() <= kMaxSuiteNTrain,
                [&] {
                  return where + ": n_train." + preset + " holds " + n.dump() +
                         ", expected integers in [4, 1e7] (validation pairs are N/4)";
                });
        ns.push_back(n.get<std::int64_t>());
      }
      reject_repeats(ns, where, "n_train." + preset);
    }
  }
  if (doc.contains("reference")) {
    s.reference = doc.at("reference");
    auto check = [&](const json& v, const std::string& at) {
      require(v.is_string() && (v == "splitting" || v == "expm" || v == "rk"), [&] {
        return where + ": " + at + " = " + v.dump() +
               ", expected \"splitting\", \"expm\" or \"rk\"";
      });
    };
    if (s.reference.is_object()) {
      for (const auto& [preset, v] : s.reference.items()) {
        preset_by_name(preset);
        check(v, "reference." + preset);
      }
    } else {
      check(s.reference, "reference");
    }
  }
  if (doc.contains("epochs")) {
    s.epochs = doc.at("epochs");
    require(s.epochs.is_object(), [&] {
      return where + ": key 'epochs' = " + s.epochs.dump() +
             ", expected {\"preset or *\": {\"model or *\": E}}";
    });
    for (const auto& item : s.epochs.items()) {  // clang 14 cannot capture bindings
      const std::string& preset = item.key();
      const json& by_model = item.value();
      if (preset != "*") preset_by_name(preset);
      require(by_model.is_object(), [&] {
        return where + ": epochs." + preset + " = " + by_model.dump() +
               ", expected {\"model or *\": E}";
      });
      for (const auto& entry : by_model.items()) {
        const std::string& model = entry.key();
        const json& e = entry.value();
        if (model != "*") model_spec_for(preset_by_name("s1"), model);
        require(e.is_number_integer() && e.get<std::int64_t>() >= 0 &&
                    e.get<std::int64_t>() <= 100000000LL,
                [&] {
                  return where + ": epochs." + preset + "." + model + " = " + e.dump() +
                         ", expected an integer in [0, 1e8]";
                });
      }
    }
  }
}

}  // namespace

SuiteSpec parse_suite(const json& doc, const std::string& where) {
  require(doc.is_object(), [&] { return where + ": expected a JSON object describing a suite"; });
  reject_unknown_keys(
      doc, where,
      {"name", "title", "kind", "vary", "columns", "presets", "models", "seeds", "sigmas",
       "n_train", "h_tests", "reference", "epochs", "extra_jacobians", "comment"});
  SuiteSpec s;
  require(doc.contains("name") && doc.at("name").is_string() &&
              !doc.at("name").get<std::string>().empty(),
          [&] { return where + ": missing key 'name' (expected a non-empty string)"; });
  s.name = doc.at("name").get<std::string>();
  for (const char c : s.name)
    require(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_', [&] {
      return where + ": name '" + s.name + "' may hold only letters, digits, '-' and '_'";
    });
  for (const char* key : {"title", "kind", "vary", "comment"})
    if (doc.contains(key) && !doc.at(key).is_string())
      throw Error(where + ": key '" + key + "' = " + doc.at(key).dump().substr(0, 80) +
                  ", expected a string");
  s.title = doc.value("title", s.name);
  s.kind = doc.value("kind", std::string("table"));
  require(s.kind == "table" || s.kind == "grid", [&] {
    return where + ": key 'kind' = '" + s.kind + "', expected \"table\" or \"grid\"";
  });
  s.presets = string_list(doc, "presets", where, preset_names());
  s.models = string_list(doc, "models", where, model_types());
  require(doc.contains("seeds"),
          [&] { return where + ": missing key 'seeds' (expected a list of integers)"; });
  for (const auto& v : doc.at("seeds")) {
    require(v.is_number_integer() && v.get<std::int64_t>() >= 0,
            [&] { return where + ": key 'seeds' holds " + v.dump() + ", expected integers >= 0"; });
    s.seeds.push_back(v.get<std::uint64_t>());
  }
  require(!s.seeds.empty(),
          [&] { return where + ": key 'seeds' is empty, expected at least one seed"; });
  reject_repeats(s.seeds, where, "seeds");
  if (doc.contains("sigmas")) s.sigmas = number_list(doc.at("sigmas"), where, "sigmas", 0, false);
  if (doc.contains("h_tests"))
    s.h_tests = number_list(doc.at("h_tests"), where, "h_tests", 0, true);
  if (doc.contains("extra_jacobians")) {
    require(doc.at("extra_jacobians").is_boolean(), [&] {
      return where + ": key 'extra_jacobians' = " + doc.at("extra_jacobians").dump() +
             ", expected true or false";
    });
    s.extra_jacobians = doc.at("extra_jacobians").get<bool>();
  }
  parse_run_options(doc, where, s);
  if (s.kind == "grid") {
    require(doc.contains("vary") && doc.at("vary").is_string(), [&] {
      return where + ": a grid suite needs key 'vary' (\"sigma\", \"n_train\" or \"h_test\")";
    });
    s.vary = doc.at("vary").get<std::string>();
    require(s.vary == "sigma" || s.vary == "n_train" || s.vary == "h_test", [&] {
      return where + ": key 'vary' = '" + s.vary + "', expected sigma, n_train or h_test";
    });
  } else {
    require(!doc.contains("vary"),
            [&] { return where + ": key 'vary' belongs to grid suites only"; });
    const std::vector<std::string> metrics = {
        "l2_error",  "residual_mean", "residual_max",           "lambda_abs_err_mean",
        "gamma_hat", "gamma_abs_err", "structure_residual_max", "params"};
    require(s.seeds.size() == 1 && s.sigmas.size() == 1 && s.h_tests.size() <= 1 &&
                (s.n_train.is_null() ||
                 std::all_of(s.n_train.begin(), s.n_train.end(),
                             [](const json& sizes) { return sizes.size() == 1; })),
            [&] {
              return where +
                     ": a table suite has one run per (preset, model): one seed, one sigma, "
                     "one n_train and one h_test (use \"kind\": \"grid\" to vary them)";
            });
    s.columns = doc.contains("columns") ? string_list(doc, "columns", where, metrics)
                                        : std::vector<std::string>{"l2_error"};
  }
  // The runs are the product of the lists; bound it before anything is expanded.
  double runs = static_cast<double>(s.models.size()) * static_cast<double>(s.seeds.size()) *
                static_cast<double>(s.sigmas.size());
  double sizes = 0.0;
  for (const auto& preset : s.presets)
    sizes += s.n_train.is_object() && s.n_train.contains(preset)
                 ? static_cast<double>(s.n_train.at(preset).size())
                 : 1.0;
  runs *= sizes;
  require(runs <= kMaxSuiteRuns, [&] {
    return where + ": the suite has " + std::to_string(static_cast<long long>(runs)) +
           " runs (presets x n_train sizes x sigmas x models x seeds); expected at most " +
           std::to_string(static_cast<long long>(kMaxSuiteRuns));
  });
  return s;
}

SuiteSpec suite_from_text(const std::string& text, const std::string& where) {
  return parse_suite(parse_json_text(text, where, "a suite file (a JSON object)"), where);
}

SuiteSpec load_suite(const std::string& path) {
  return suite_from_text(read_text_file(path), path);
}

long suite_epochs(const SuiteSpec& s, const std::string& preset, const std::string& model) {
  for (const std::string& p : {preset, std::string("*")}) {
    if (!s.epochs.contains(p)) continue;
    for (const std::string& m : {model, std::string("*")})
      if (s.epochs.at(p).contains(m)) return s.epochs.at(p).at(m).get<long>();
  }
  return train_options_for(preset_by_name(preset), model).epochs;
}

std::vector<SuiteRun> expand_suite(const SuiteSpec& s) {
  std::vector<SuiteRun> runs;
  for (const auto& preset_name : s.presets) {
    const Preset base = preset_by_name(preset_name);
    // Parameter counts for the cost model, once per model (building one is not free).
    std::vector<double> params;
    for (const auto& model : s.models)
      params.push_back(static_cast<double>(make_model(model_spec_for(base, model)).n_params()));
    for (const Index n : n_train_for(s, base)) {
      for (const double sigma : s.sigmas) {
        for (std::size_t m = 0; m < s.models.size(); ++m) {
          const std::string& model = s.models[m];
          for (const std::uint64_t seed : s.seeds) {
            SuiteRun r;
            RunConfig& c = r.config;
            c = default_run_config(preset_name, model);
            c.preset.n_train = n;
            c.preset.n_val = std::max<Index>(1, n / 4);
            c.seed = seed;
            c.sigma = sigma;
            c.train.epochs = suite_epochs(s, preset_name, model);
            c.reference.method = parse_reference(reference_for(s, preset_name));
            r.h_tests = s.h_tests.empty() ? std::vector<double>{base.h_test} : s.h_tests;
            c.preset.h_test = r.h_tests.front();
            r.extra_jacobians = s.extra_jacobians || r.h_tests.size() == 1;
            c.validate();
            const std::string canonical =
                json(c).dump() + json(r.h_tests).dump() + (r.extra_jacobians ? "J" : "");
            r.key = preset_name + "-" + model + "-seed" + std::to_string(seed) + "-sigma" +
                    compact(sigma) + "-n" + std::to_string(n) + "-" + hex64(fnv1a64(canonical));
            // Cost model for scheduling only: epochs x parameters, fields a few times dearer.
            const double per_epoch =
                params[m] * static_cast<double>(n) * (is_vector_field_type(model) ? 4 : 1);
            r.cost = static_cast<double>(c.train.epochs) * per_epoch;
            runs.push_back(std::move(r));
          }
        }
      }
    }
  }
  return runs;
}

}  // namespace csympnet
