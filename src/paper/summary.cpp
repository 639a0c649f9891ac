#include "csympnet/paper/summary.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

#include "csympnet/core/error.hpp"
#include "csympnet/paper/paper_values.hpp"

namespace csympnet {

namespace {

using nlohmann::json;

constexpr double kInf = std::numeric_limits<double>::infinity();

// A metric of a record; JSON null (how a non-finite number is stored) reads as +inf.
double metric(const json& diag, const std::string& key) {
  if (!diag.contains(key) || diag.at(key).is_null()) return kInf;
  return diag.at(key).get<double>();
}

json paper_json(const std::string& preset, const std::string& model) {
  const auto p = paper_values(preset, model);
  if (!p) return nullptr;
  json j = {{"params", p->params}, {"l2_error", p->l2_error}};
  if (p->residual_mean) j["residual_mean"] = *p->residual_mean;
  if (p->residual_max) j["residual_max"] = *p->residual_max;
  if (p->lambda_abs_err_mean) j["lambda_abs_err_mean"] = *p->lambda_abs_err_mean;
  if (p->gamma_hat) j["gamma_hat"] = *p->gamma_hat;
  if (p->gamma_abs_err) j["gamma_abs_err"] = *p->gamma_abs_err;
  return j;
}

json table_entry(const json& rec) {
  json e = {{"status", rec.at("status")}, {"key", rec.at("key")}};
  if (rec.at("status") != "ok") {
    e["error"] = rec.value("error", "");
    return e;
  }
  const json& rep = rec.at("report");
  const json& diag = rec.at("by_h_test").at(0);
  for (const char* k :
       {"l2_error", "residual_mean", "residual_max", "lambda_hat_mean", "lambda_abs_err_mean",
        "structure_residual_max", "gamma_hat", "gamma_abs_err"})
    e[k] = diag.contains(k) ? diag.at(k) : json(nullptr);
  for (const char* k :
       {"params", "epochs", "best_epoch", "stop_reason", "best_val_loss", "test_redraws", "recipe"})
    e[k] = rep.at(k);
  e["seed"] = rec.at("config").at("seed");
  e["sigma"] = rec.at("config").at("sigma");
  e["reference"] = rec.at("config").at("reference").at("method");
  return e;
}

// Median and quartiles, and the per-seed values (for the figures); non-finite → null.
json stats_of(const std::vector<double>& v) {
  if (v.empty()) return nullptr;
  json j = {{"median", quantile(v, 0.5)}, {"q1", quantile(v, 0.25)}, {"q3", quantile(v, 0.75)}};
  for (auto& [k, x] : j.items())
    if (!std::isfinite(x.get<double>())) x = nullptr;
  json values = json::array();
  for (const double x : v) values.push_back(std::isfinite(x) ? json(x) : json(nullptr));
  j["values"] = values;
  return j;
}

std::string cell_text(const json& v, const char* pattern = "%.3e") {
  if (v.is_null()) return "-";
  if (v.is_string()) return v.get<std::string>();
  if (v.is_number_integer()) return std::to_string(v.get<long long>());
  const double x = v.get<double>();
  if (!std::isfinite(x)) return "inf";
  char buf[48];
  std::snprintf(buf, sizeof buf, pattern, x);
  return buf;
}

const char* model_label(const std::string& m) {
  static const std::map<std::string, const char*> labels = {{"csympnet", "CSympNet-ID"},
                                                            {"sympnet", "SympNet"},
                                                            {"map", "MapBaseline"},
                                                            {"ode", "ODEBaseline"},
                                                            {"dhnn", "DHNN"},
                                                            {"dhnn2", "DHNN2"},
                                                            {"phnn", "pHNN"},
                                                            {"phnn2", "pHNN2"}};
  const auto it = labels.find(m);
  return it == labels.end() ? m.c_str() : it->second;
}

const char* column_label(const std::string& c) {
  static const std::map<std::string, const char*> labels = {
      {"l2_error", "L2"},
      {"residual_mean", "E[R]"},
      {"residual_max", "max R"},
      {"lambda_abs_err_mean", "E|lambda-lambda*|"},
      {"gamma_hat", "gamma_hat"},
      {"gamma_abs_err", "|gamma_hat-gamma|"},
      {"structure_residual_max", "max S"},
      {"params", "params"},
      {"train_seconds", "train s"}};
  const auto it = labels.find(c);
  return it == labels.end() ? c.c_str() : it->second;
}

// A '|' inside a Markdown table cell ends the cell unless escaped.
std::string md_escape(const std::string& s) {
  std::string out;
  for (const char c : s) {
    if (c == '|') out += '\\';
    out += c;
  }
  return out;
}

// Text for LaTeX's text mode: its ten special characters escaped.
std::string latex_escape(const std::string& s) {
  std::string out;
  for (const char c : s) {
    switch (c) {
      case '_':
      case '%':
      case '&':
      case '#':
      case '$':
      case '{':
      case '}':
        out += '\\';
        out += c;
        break;
      case '\\':
        out += "\\textbackslash{}";
        break;
      case '~':
        out += "\\textasciitilde{}";
        break;
      case '^':
        out += "\\textasciicircum{}";
        break;
      case '|':
        out += "\\textbar{}";
        break;
      default:
        out += c;
    }
  }
  return out;
}

// A metric's column heading in LaTeX (math where the paper uses symbols).
std::string latex_column(const std::string& c) {
  static const std::map<std::string, const char*> labels = {
      {"l2_error", "$L^2$"},
      {"residual_mean", "$E[R]$"},
      {"residual_max", "$\\max R$"},
      {"lambda_abs_err_mean", "$E|\\hat\\lambda-\\lambda^*|$"},
      {"gamma_hat", "$\\hat\\gamma$"},
      {"gamma_abs_err", "$|\\hat\\gamma-\\gamma|$"},
      {"structure_residual_max", "$\\max S$"},
      {"params", "params"},
      {"train_seconds", "train (s)"}};
  const auto it = labels.find(c);
  return it == labels.end() ? latex_escape(c) : std::string(it->second);
}

// A caption's opening from a suite title. LaTeX numbers the float itself, so the paper's
// numbering in a title "Table 2: what" moves to the end: "what (the paper's Table 2)".
std::string latex_caption_title(const std::string& title) {
  const std::string prefix = "Table ";
  std::size_t end = prefix.size();
  while (end < title.size() && std::isdigit(static_cast<unsigned char>(title[end]))) ++end;
  if (title.rfind(prefix, 0) != 0 || end == prefix.size() || title.compare(end, 2, ": ") != 0)
    return latex_escape(title);
  return latex_escape(title.substr(end + 2)) + " (the paper's Table " +
         title.substr(prefix.size(), end - prefix.size()) + ")";
}

// The opening of a booktabs table float: caption, label, and the tabular's column spec.
std::string latex_open(const std::string& caption, const std::string& label,
                       const std::string& spec) {
  return "\\begin{table}[htbp]\n\\centering\n\\small\n\\caption{" + caption + "}\n\\label{" +
         label + "}\n\\begin{tabular}{" + spec + "}\n\\toprule\n";
}

const char* const kLatexClose = "\\bottomrule\n\\end{tabular}\n\\end{table}\n";

// A number cell: the same text as in the Markdown and CSV tables, with an en dash for none.
std::string latex_cell(const std::string& text) {
  return text == "-" ? "--" : text;
}

}  // namespace

double quantile(std::vector<double> v, double q) {
  require(!v.empty(), "quantile of an empty set");
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  const double frac = pos - static_cast<double>(lo);
  if (frac == 0.0 || v[lo] == v[hi]) return v[lo];
  return v[lo] + frac * (v[hi] - v[lo]);
}

json summarize(const std::vector<SuiteSpec>& suites, const RecordLookup& record_of) {
  json out = {{"suites", json::array()}, {"checks", json::object()}};
  for (const SuiteSpec& s : suites) {
    out["suites"].push_back(s.name);
    json& js = out[s.name];
    js = json::object();
    js["title"] = s.title;
    js["kind"] = s.kind;
    if (s.kind == "grid") js["vary"] = s.vary;
    const auto runs = expand_suite(s);
    // (preset, model, sigma, n_train, h_test) → per-seed values.
    struct Cell {
      double sigma = 0;
      long n_train = 0;
      double h_test = 0;
      std::vector<double> l2, gamma_err, lambda_hat, lambda_err;
      std::vector<std::uint64_t> seeds;
      long failed = 0;
      double lambda_star = 0;
    };
    std::map<std::string, std::map<std::string, std::vector<Cell>>> cells;
    for (const SuiteRun& run : runs) {
      const auto rec = record_of(run);
      require(rec.has_value(),
              [&] { return "suite " + s.name + ": run " + run.key + " has no record"; });
      const std::string& preset = run.config.preset.name;
      const std::string& model = run.config.model;
      if (s.kind == "table") {
        json e = table_entry(*rec);
        e["paper"] = paper_json(preset, model);
        js[preset][model] = e;
        continue;
      }
      for (std::size_t i = 0; i < run.h_tests.size(); ++i) {
        auto& list = cells[preset][model];
        auto it = std::find_if(list.begin(), list.end(), [&](const Cell& c) {
          return c.sigma == run.config.sigma && c.n_train == run.config.preset.n_train &&
                 c.h_test == run.h_tests[i];
        });
        if (it == list.end()) {
          Cell fresh;
          fresh.sigma = run.config.sigma;
          fresh.n_train = static_cast<long>(run.config.preset.n_train);
          fresh.h_test = run.h_tests[i];
          list.push_back(std::move(fresh));
          it = list.end() - 1;
        }
        it->seeds.push_back(run.config.seed);
        if ((*rec)["status"] != "ok") {
          ++it->failed;
          continue;
        }
        const json& diag = rec->at("by_h_test").at(i);
        it->l2.push_back(metric(diag, "l2_error"));
        if (diag.at("jacobian_points").get<long>() > 0) {
          it->lambda_hat.push_back(metric(diag, "lambda_hat_mean"));
          it->lambda_err.push_back(metric(diag, "lambda_abs_err_mean"));
        }
        it->lambda_star = metric(diag, "lambda_star");
        if (!diag.at("gamma_abs_err").is_null())
          it->gamma_err.push_back(diag.at("gamma_abs_err").get<double>());
      }
    }
    for (auto& [preset, by_model] : cells) {
      for (auto& [model, list] : by_model) {
        json arr = json::array();
        for (const Cell& c : list) {
          arr.push_back({{"sigma", c.sigma},
                         {"n_train", c.n_train},
                         {"h_test", c.h_test},
                         {"seeds", c.seeds},
                         {"failed", c.failed},
                         {"lambda_star", c.lambda_star},
                         {"l2_error", stats_of(c.l2)},
                         {"gamma_abs_err", stats_of(c.gamma_err)},
                         {"lambda_hat", stats_of(c.lambda_hat)},
                         {"lambda_abs_err", stats_of(c.lambda_err)}});
        }
        js[preset][model] = arr;
      }
    }
    if (s.kind == "table") {
      for (const auto& preset : s.presets) {
        std::string best;
        double best_l2 = kInf;
        for (const auto& model : s.models) {
          const json& e = js[preset][model];
          const double l2 = e.at("status") == "ok" ? metric(e, "l2_error") : kInf;
          if (l2 < best_l2) {
            best_l2 = l2;
            best = model;
          }
        }
        out["checks"][s.name][preset] = {
            {"best_l2_model", best.empty() ? json() : json(best)},
            {"best_l2", std::isfinite(best_l2) ? json(best_l2) : json(nullptr)}};
      }
    }
  }
  return out;
}

json timings(const std::vector<SuiteSpec>& suites, const RecordLookup& record_of) {
  json out = json::object();
  for (const SuiteSpec& s : suites) {
    for (const SuiteRun& run : expand_suite(s)) {
      const auto rec = record_of(run);
      if (!rec || (*rec)["status"] != "ok") continue;
      out[s.name][run.key] = {{"train_seconds", rec->at("report").at("train_seconds")},
                              {"eval_seconds", rec->at("report").at("eval_seconds")},
                              {"epochs", rec->at("report").at("epochs")}};
    }
  }
  return out;
}

TableFiles render_tables(const SuiteSpec& s, const json& summary) {
  TableFiles f;
  const json& js = summary.at(s.name);
  std::string& md = f.markdown;
  std::string& csv = f.csv;
  std::string& tex = f.latex;
  md = "# " + s.title + "\n\n";
  if (s.kind == "table") {
    md +=
        "Each metric: ours, the paper's value where it reports one, and ours / paper.[^ratio]\n\n";
    csv = "preset,model,metric,ours,paper,ratio\n";
    tex = "% " + s.title + "\n% Needs \\usepackage{booktabs}.\n" +
          latex_open(latex_caption_title(s.title) +
                         ". Each metric: ours, the paper's value where it reports one, and ours "
                         "/ paper.",
                     "tab:" + s.name, "ll" + std::string(s.columns.size() * 3, 'r'));
    std::string rules;
    tex += " & ";
    for (std::size_t i = 0; i < s.columns.size(); ++i) {
      tex += " & \\multicolumn{3}{c}{" + latex_column(s.columns[i]) + "}";
      rules +=
          "\\cmidrule(lr){" + std::to_string(3 + 3 * i) + "-" + std::to_string(5 + 3 * i) + "}";
    }
    tex += " \\\\\n" + rules + "\nPreset & Model";
    for (std::size_t i = 0; i < s.columns.size(); ++i) tex += " & ours & paper & ratio";
    tex += " \\\\\n\\midrule\n";
    for (const auto& preset : s.presets) {
      if (&preset != &s.presets.front()) tex += "\\midrule\n";
      md += "## " + preset + "\n\n| model |";
      std::string rule = "|---|";
      for (const auto& c : s.columns) {
        md += " " + md_escape(column_label(c)) + " | paper | ratio |";
        rule += "---:|---:|---:|";
      }
      md += "\n" + rule + "\n";
      for (const auto& model : s.models) {
        const json& e = js.at(preset).at(model);
        md += std::string("| ") + model_label(model) + " |";
        tex += (&model == &s.models.front() ? latex_escape(preset) : std::string()) + " & " +
               latex_escape(model_label(model));
        for (const auto& c : s.columns) {
          const json ours = e.contains(c) ? e.at(c) : json(nullptr);
          const json paper =
              e.at("paper").is_object() && e.at("paper").contains(c) ? e.at("paper").at(c) : json();
          json ratio = nullptr;
          if (ours.is_number() && paper.is_number() && paper.get<double>() != 0.0)
            ratio = ours.get<double>() / paper.get<double>();
          const char* pat = c == "gamma_hat" ? "%.8f" : "%.3e";
          const std::string o = e.at("status") == "ok" ? cell_text(ours, pat) : "failed";
          md += " " + o + " | " + cell_text(paper, pat) + " | " + cell_text(ratio, "%.3g") + " |";
          csv += preset + "," + model + "," + c + "," + o + "," + cell_text(paper, pat) + "," +
                 cell_text(ratio, "%.3g") + "\n";
          tex += " & " + latex_cell(o) + " & " + latex_cell(cell_text(paper, pat)) + " & " +
                 latex_cell(cell_text(ratio, "%.3g"));
        }
        md += "\n";
        tex += " \\\\\n";
      }
      const json& check = summary.at("checks").at(s.name).at(preset);
      if (std::find(s.columns.begin(), s.columns.end(), "l2_error") != s.columns.end())
        md += "\nSmallest L2 error: " +
              (check.at("best_l2_model").is_null()
                   ? std::string("none")
                   : std::string(model_label(check.at("best_l2_model").get<std::string>()))) +
              ".\n";
      md += "\n";
    }
    tex += kLatexClose;
    md +=
        "[^ratio]: A ratio far from 1 is not a failure to reproduce. The paper does not publish "
        "its test starts; ours are drawn from seed 0 (docs/protocol.md, \"Test trajectories\"), "
        "so every model's L2 error, CSympNet-ID's included, differs from the paper's (on s1 "
        "ours are several times larger for every model). The paper's ordering of the models "
        "is what carries over; docs/baselines.md (\"Results beside the paper's Tables 2 and "
        "3\") gives the measured reason for each model's gap.\n";
    return f;
  }
  // Grid suites: one row per cell, median [q1, q3] over seeds.
  md += "Median [q1, q3] over " + std::to_string(s.seeds.size()) + " seeds; varied: " + s.vary +
        ".\n\n";
  md +=
      "| preset | model | sigma | N_train | h_test | L2 | \\|gamma_hat-gamma\\| | lambda_hat "
      "(lambda*) | failed |\n|---|---|---:|---:|---:|---:|---:|---:|---:|\n";
  csv =
      "preset,model,sigma,n_train,h_test,l2_median,l2_q1,l2_q3,gamma_err_median,gamma_err_q1,"
      "gamma_err_q3,lambda_hat_median,lambda_hat_q1,lambda_hat_q3,lambda_star,failed\n";
  // LaTeX: one table per preset (a grid suite has dozens of rows per preset).
  tex = "% " + s.title + "\n% Needs \\usepackage{booktabs}.\n";
  auto iqr = [](const json& st, const char* pat) {
    if (st.is_null()) return std::string("-");
    return cell_text(st.at("median"), pat) + " [" + cell_text(st.at("q1"), pat) + ", " +
           cell_text(st.at("q3"), pat) + "]";
  };
  auto three = [](const json& st) {
    if (st.is_null()) return std::string("-,-,-");
    return cell_text(st.at("median"), "%.6e") + "," + cell_text(st.at("q1"), "%.6e") + "," +
           cell_text(st.at("q3"), "%.6e");
  };
  for (const auto& preset : s.presets) {
    tex += "\n" +
           latex_open(latex_caption_title(s.title) + ". System " + latex_escape(preset) +
                          "; $L^2$ and " + "$|\\hat\\gamma-\\gamma|$: median [$q_1$, $q_3$] over " +
                          std::to_string(s.seeds.size()) + " seeds; $\\hat\\lambda$: median.",
                      "tab:" + s.name + "-" + preset, "lrrrrrr") +
           "Model & $\\sigma$ & $N_{\\mathrm{train}}$ & $h_{\\mathrm{test}}$ & $L^2$ & "
           "$|\\hat\\gamma-\\gamma|$ & $\\hat\\lambda$ \\\\\n\\midrule\n";
    for (const auto& model : s.models) {
      if (&model != &s.models.front()) tex += "\\addlinespace\n";
      bool first = true;
      for (const json& c : js.at(preset).at(model)) {
        const std::string sig = cell_text(c.at("sigma"), "%g"), n = cell_text(c.at("n_train")),
                          h = cell_text(c.at("h_test"), "%g");
        md += "| " + preset + " | " + model_label(model) + " | " + sig + " | " + n + " | " + h +
              " | " + iqr(c.at("l2_error"), "%.3e") + " | " + iqr(c.at("gamma_abs_err"), "%.2e") +
              " | " + iqr(c.at("lambda_hat"), "%.6f") + " (" +
              cell_text(c.at("lambda_star"), "%.6f") + ") | " + cell_text(c.at("failed")) + " |\n";
        csv += preset + "," + model + "," + sig + "," + n + "," + h + "," +
               three(c.at("l2_error")) + "," + three(c.at("gamma_abs_err")) + "," +
               three(c.at("lambda_hat")) + "," + cell_text(c.at("lambda_star"), "%.12g") + "," +
               cell_text(c.at("failed")) + "\n";
        tex +=
            (first ? latex_escape(model_label(model)) : std::string()) + " & " + sig + " & " + n +
            " & " + h + " & " + latex_cell(iqr(c.at("l2_error"), "%.2e")) + " & " +
            latex_cell(iqr(c.at("gamma_abs_err"), "%.1e")) + " & " +
            latex_cell(cell_text(
                c.at("lambda_hat").is_null() ? json() : c.at("lambda_hat").at("median"), "%.5f")) +
            " \\\\\n";
        first = false;
      }
    }
    tex += kLatexClose;
  }
  return f;
}

}  // namespace csympnet
