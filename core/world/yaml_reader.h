#ifndef ROOMFIX_CORE_WORLD_YAML_READER_H_
#define ROOMFIX_CORE_WORLD_YAML_READER_H_

#include <yaml-cpp/yaml.h>

#include <array>
#include <cstddef>
#include <functional>
#include <initializer_list>
#include <stdexcept>
#include <string>

namespace roomfix {

// What YamlReader throws on the first problem: one line
// "FILE:LINE: KEY: WHAT". It is thrown inside a parser only and turned into
// the returned error at the parser's API boundary (LoadSite,
// LoadCalibration); it never escapes those.
struct YamlError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Reads typed values out of a YAML tree for the project's configuration
// files (site, calibration), naming the file, the line and the key path in
// every failure. Strict: unknown keys, wrong types and non-finite numbers
// are errors, so a typo never leaves a default silently in place.
class YamlReader {
 public:
  explicit YamlReader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void Fail(const YAML::Node& near, const std::string& key,
                         const std::string& what) const;
  void ExpectMap(const YAML::Node& node, const std::string& key) const;
  void ExpectSequence(const YAML::Node& node, const std::string& key) const;
  void OnlyKeys(const YAML::Node& map, const std::string& key,
                std::initializer_list<const char*> allowed) const;
  YAML::Node Required(const YAML::Node& map, const std::string& key, const std::string& name) const;
  double Double(const YAML::Node& node, const std::string& key) const;
  double Positive(const YAML::Node& node, const std::string& key) const;
  int Int(const YAML::Node& node, const std::string& key) const;
  bool Bool(const YAML::Node& node, const std::string& key) const;
  std::string String(const YAML::Node& node, const std::string& key) const;

  template <size_t N>
  std::array<double, N> Doubles(const YAML::Node& node, const std::string& key) const {
    if (!node.IsSequence() || node.size() != N) {
      Fail(node, key, "expected a list of " + std::to_string(N) + " numbers");
    }
    std::array<double, N> out{};
    for (size_t i = 0; i < N; ++i) out[i] = Double(node[i], Index(key, i));
    return out;
  }

  template <size_t N>
  std::array<int, N> Ints(const YAML::Node& node, const std::string& key) const {
    if (!node.IsSequence() || node.size() != N) {
      Fail(node, key, "expected a list of " + std::to_string(N) + " integers");
    }
    std::array<int, N> out{};
    for (size_t i = 0; i < N; ++i) out[i] = Int(node[i], Index(key, i));
    return out;
  }

  // Key paths: Join("cameras[0]", "id") is "cameras[0].id", Index("rx", 2)
  // is "rx[2]".
  static std::string Join(const std::string& key, const std::string& name);
  static std::string Index(const std::string& key, size_t i);
  // "a mapping", "a list", "'text'" or "nothing", for messages.
  static std::string Kind(const YAML::Node& node);

 private:
  std::string file_;
};

// The first key repeated within one mapping of the (first) document, as
// "FILE:LINE: duplicated key 'x' (first at line N)" with FILE = `name`, or ""
// when no key repeats. The text must be valid YAML (YAML::Load accepted it).
std::string FindDuplicateKey(const std::string& yaml_text, const std::string& name);

// Parses one YAML document whose top level must be a mapping and hands it
// to `parse` with a reader for `name` (the file, for messages). Returns false
// with the one-line error of the first problem: a YAML syntax error, a
// non-mapping document, a duplicated key (FindDuplicateKey), whatever `parse` reports through the
// reader, or a value of a shape that a typed read did not anticipate. Nothing escapes.
bool ParseYamlDocument(const std::string& yaml_text, const std::string& name,
                       const std::function<void(const YamlReader&, const YAML::Node&)>& parse,
                       std::string* error);

}  // namespace roomfix

#endif  // ROOMFIX_CORE_WORLD_YAML_READER_H_
