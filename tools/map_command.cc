// roomfix map: pixels to floor positions (or back) through a calibration
// file, one CSV line in, one out.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "core/calib/calibration_file.h"
#include "core/world/file_io.h"
#include "tools/commands.h"

namespace roomfix {
namespace {

// Three numbers separated by commas; false for anything else.
bool ParseLine(const std::string& line, double out[3]) {
  std::stringstream s(line);
  std::string field;
  int n = 0;
  while (std::getline(s, field, ',')) {
    if (n == 3) return false;
    const char* begin = field.c_str();
    char* end = nullptr;
    out[n] = std::strtod(begin, &end);
    while (*end == ' ' || *end == '\t' || *end == '\r') ++end;
    if (end == begin || *end != '\0') return false;
    ++n;
  }
  return n == 3;
}

}  // namespace

void AddMapCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "map",
      "Map CSV lines u,v,height_m to x_m,y_m,height_m through a calibration file (with "
      "--inverse, x_m,y_m,height_m to u_px,v_px,height_m)");
  auto calibration = std::make_shared<std::string>();
  auto input = std::make_shared<std::string>("-");
  auto inverse = std::make_shared<bool>(false);
  cmd->add_option("--calibration", *calibration, "Calibration YAML (full or regions)")->required();
  cmd->add_flag("--inverse", *inverse, "Floor point to pixel");
  cmd->add_option("FILE", *input, "Input CSV, or - for standard input")->capture_default_str();
  cmd->callback([calibration, input, inverse, exit_code] {
    calib::Calibration cal;
    std::string error;
    if (!calib::LoadCalibration(*calibration, &cal, &error)) {
      std::cerr << "roomfix map: " << error << "\n";
      *exit_code = 1;
      return;
    }
    std::ifstream file;
    std::istream* in = &std::cin;
    if (*input != "-") {
      file.open(*input);
      if (!file) {
        std::cerr << "roomfix map: " << *input << ": cannot open\n";
        *exit_code = 1;
        return;
      }
      in = &file;
    }
    const std::string name = *input == "-" ? "stdin" : *input;
    // The height is echoed so that the output of one direction is the input
    // of the other (map | map --inverse).
    std::cout << (*inverse ? "u_px,v_px,height_m\n" : "x_m,y_m,height_m\n");
    // 12 significant digits: 1e-9 of a 1000 px coordinate, far below any
    // calibration's accuracy, and round trips within 1e-6.
    std::cout << std::setprecision(12);
    std::string line;
    int number = 0;
    int failures = 0;
    bool first = true;
    for (;;) {
      const LineRead read = ReadBoundedLine(*in, &line);
      if (read == LineRead::kEnd) break;
      ++number;
      if (read == LineRead::kTooLong) {
        // Not a text input (/dev/zero, a binary file): stop, do not grow.
        std::cerr << "roomfix map: " << *input << ":" << number << ": line longer than "
                  << ByteSizeText(kMaxInputLineBytes) << ": not a text input\n";
        *exit_code = 1;
        return;
      }
      if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
      double v[3];
      if (!ParseLine(line, v)) {
        // A header line (u,v,height_m or x_m,y_m,height_m) is allowed first.
        if (first && line.find_first_of("0123456789") == std::string::npos) {
          first = false;
          continue;
        }
        std::cerr << "roomfix map: " << name << ":" << number << ": expected "
                  << (*inverse ? "x_m,y_m,height_m" : "u,v,height_m") << "\n";
        std::cout << "nan,nan,nan\n";
        ++failures;
        continue;
      }
      first = false;
      double a, b;
      const bool ok = *inverse ? cal.FloorToPixel(v[0], v[1], v[2], &a, &b, &error)
                               : cal.PixelToFloor(v[0], v[1], v[2], &a, &b, &error);
      if (!ok) {
        std::cerr << "roomfix map: " << name << ":" << number << ": " << error << "\n";
        std::cout << "nan,nan," << v[2] << "\n";
        ++failures;
        continue;
      }
      std::cout << a << "," << b << "," << v[2] << "\n";
    }
    *exit_code = failures > 0 ? 2 : 0;
  });
}

}  // namespace roomfix
