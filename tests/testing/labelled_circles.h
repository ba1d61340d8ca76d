#ifndef ROOMFIX_TESTS_TESTING_LABELLED_CIRCLES_H_
#define ROOMFIX_TESTS_TESTING_LABELLED_CIRCLES_H_

// The circles of ../shared/data/opencv_samples/derived_smarties_circles.csv
// (id,center_x_px,center_y_px,radius_px,colour_label): the candies of the
// real photo smarties.png, labelled by colour.

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace roomfix::testing {

struct LabelledCircle {
  double u = 0.0;
  double v = 0.0;
  double r = 0.0;
  std::string colour;
};

// Every well-formed row after the header; none for a missing file.
inline std::vector<LabelledCircle> ReadLabelledCircles(const std::string& path) {
  std::vector<LabelledCircle> labels;
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string id, u, v, r, colour;
    if (std::getline(ss, id, ',') && std::getline(ss, u, ',') && std::getline(ss, v, ',') &&
        std::getline(ss, r, ',') && std::getline(ss, colour)) {
      labels.push_back({std::stod(u), std::stod(v), std::stod(r), colour});
    }
  }
  return labels;
}

}  // namespace roomfix::testing

#endif  // ROOMFIX_TESTS_TESTING_LABELLED_CIRCLES_H_
