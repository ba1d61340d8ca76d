// roomfix solve: one trilateration problem per JSON line in, one answer per
// line out.
#include <CLI/CLI.hpp>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "core/trilat/trilateration.h"
#include "core/world/file_io.h"
#include "tools/commands.h"

namespace roomfix {
namespace {

using nlohmann::json;

// A JSON number, or null for NaN and infinities.
json Number(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

// Parses {"anchors": [[x,y(,z)],...], "distances": [...], "height": h,
// "method": "...", "sigma": s} and solves it; false with the reason.
bool SolveOne(const json& in, json* answer, std::string* error) {
  auto refuse = [error](std::string reason) {
    *error = std::move(reason);
    return false;
  };
  if (!in.is_object()) return refuse("expected a JSON object");
  if (!in.contains("anchors") || !in["anchors"].is_array()) {
    return refuse("\"anchors\" must be a list of [x, y] or [x, y, z]");
  }
  if (!in.contains("distances") || !in["distances"].is_array()) {
    return refuse("\"distances\" must be a list of numbers");
  }
  const json& anchors = in["anchors"];
  const json& distances = in["distances"];
  if (anchors.size() != distances.size()) {
    return refuse("\"anchors\" and \"distances\" differ in length (" +
                  std::to_string(anchors.size()) + " and " + std::to_string(distances.size()) +
                  ")");
  }
  size_t dim = 0;
  std::vector<trilat::RangeMeasurement> ranges;
  for (size_t i = 0; i < anchors.size(); ++i) {
    const json& a = anchors[i];
    if (!a.is_array() || (a.size() != 2 && a.size() != 3)) {
      return refuse("anchor " + std::to_string(i) + " must be [x, y] or [x, y, z]");
    }
    if (dim == 0) dim = a.size();
    if (a.size() != dim) return refuse("anchors mix 2 and 3 coordinates");
    trilat::RangeMeasurement m;
    m.receiver_id = static_cast<int>(i);
    for (size_t k = 0; k < dim; ++k) {
      if (!a[k].is_number()) return refuse("anchor " + std::to_string(i) + " is not numeric");
      m.receiver_m[static_cast<int>(k)] = a[k].get<double>();
    }
    // null stands for a missing or non-finite distance; the solver drops it.
    m.range_m = distances[i].is_number() ? distances[i].get<double>()
                                         : std::numeric_limits<double>::quiet_NaN();
    if (!distances[i].is_number() && !distances[i].is_null()) {
      return refuse("distance " + std::to_string(i) + " is not a number");
    }
    ranges.push_back(m);
  }
  trilat::SolverOptions options;
  if (in.contains("height")) {
    if (!in["height"].is_number()) return refuse("\"height\" must be a number");
    options.dimension = trilat::Dimension::kFixedHeight2D;
    options.fixed_height_m = in["height"].get<double>();
  } else {
    options.dimension = dim == 3 ? trilat::Dimension::k3D : trilat::Dimension::kPlanar2D;
  }
  if (in.contains("method")) {
    if (!in["method"].is_string() ||
        !trilat::ParseMethod(in["method"].get<std::string>(), &options.method)) {
      return refuse("\"method\" must be \"nelder-mead\", \"default\", \"robust\" or \"cauchy\"");
    }
  }
  if (in.contains("sigma")) {
    if (!in["sigma"].is_number()) return refuse("\"sigma\" must be a number");
    options.range_sigma_m = in["sigma"].get<double>();
  }
  if (!options.IsValid(error)) return false;

  const trilat::Fix fix = trilat::Solve(ranges, options);
  const int n = options.dimension == trilat::Dimension::kPlanar2D ? 2 : 3;
  json out;
  json position = json::array();
  json covariance = json::array();
  for (int r = 0; r < n; ++r) {
    position.push_back(Number(fix.position_m[r]));
    json row = json::array();
    for (int c = 0; c < n; ++c) row.push_back(Number(fix.covariance_m2(r, c)));
    covariance.push_back(row);
  }
  out["position"] = position;
  out["covariance"] = covariance;
  out["residual_rms"] = Number(fix.residual_rms_m);
  out["shared_level"] = Number(fix.shared_level_m);
  out["used"] = fix.used;
  json rejected = json::array();
  for (const auto& r : fix.rejected) {
    rejected.push_back(
        {{"index", r.receiver_id}, {"reason", trilat::RangeRejectionName(r.reason)}});
  }
  out["rejected"] = rejected;
  out["status"] = fix.status == trilat::FixStatus::kOk         ? "ok"
                  : fix.status == trilat::FixStatus::kDegraded ? "degraded"
                                                               : "failed";
  out["flags"] = trilat::DescribeFlags(fix.flags);
  out["method"] = trilat::MethodName(options.method);
  out["iterations"] = fix.iterations;
  *answer = std::move(out);
  return true;
}

// One input line's answer: the solution, or {"line": N, "error": WHY}.
// nlohmann reports a syntax error by throwing: caught here, where the
// library is called.
bool AnswerLine(const std::string& line, int number, json* answer) {
  json in;
  std::string why;
  try {
    in = json::parse(line);
  } catch (const json::exception& e) {
    // json::parse_error's text starts with its own "[json.exception...]".
    why = e.what();
    const size_t bracket = why.find("] ");
    if (why.rfind("[json.exception", 0) == 0 && bracket != std::string::npos) {
      why = why.substr(bracket + 2);
    }
  }
  if (why.empty() && SolveOne(in, answer, &why)) return true;
  *answer = {{"line", number}, {"error", why}};
  return false;
}

}  // namespace

void AddSolveCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "solve",
      "Trilaterate one problem per JSON line ({\"anchors\": [[x,y,z],...], \"distances\": [...], "
      "\"height\": h, \"method\": \"default\"}) and print one JSON answer per line");
  auto input = std::make_shared<std::string>("-");
  cmd->add_option("FILE", *input, "Input file, or - for standard input")->capture_default_str();
  cmd->callback([input, exit_code] {
    std::ifstream file;
    std::istream* in = &std::cin;
    if (*input != "-") {
      file.open(*input);
      if (!file) {
        std::cerr << "roomfix solve: " << *input << ": cannot open\n";
        *exit_code = 1;
        return;
      }
      in = &file;
    }
    std::string line;
    int number = 0;
    int failures = 0;
    for (;;) {
      const LineRead read = ReadBoundedLine(*in, &line);
      if (read == LineRead::kEnd) break;
      ++number;
      if (read == LineRead::kTooLong) {
        // Not a text input (/dev/zero, a binary file): stop, do not grow.
        std::cerr << "roomfix solve: " << *input << ":" << number << ": line longer than "
                  << ByteSizeText(kMaxInputLineBytes) << ": not a text input\n";
        *exit_code = 1;
        return;
      }
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      json answer;
      if (!AnswerLine(line, number, &answer)) ++failures;
      std::cout << answer.dump() << "\n";
    }
    *exit_code = failures > 0 ? 2 : 0;
  });
}

}  // namespace roomfix
