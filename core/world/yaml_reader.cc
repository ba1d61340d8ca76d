#include "core/world/yaml_reader.h"

#include <yaml-cpp/eventhandler.h>

#include <cmath>
#include <map>
#include <sstream>
#include <vector>

namespace roomfix {
namespace {

// Finds a key repeated within one mapping. yaml-cpp's YAML::Load keeps every
// pair but a lookup returns the first, so a repeated key would silently
// lose its later value. Run on the parser's events rather than a walk of the
// loaded tree: aliases are events here, not re-expanded subtrees, so the
// check is linear in the text however the document nests its anchors.
class DuplicateKeyFinder : public YAML::EventHandler {
 public:
  explicit DuplicateKeyFinder(std::string file) : file_(std::move(file)) {}

  const std::string& error() const { return error_; }

  void OnDocumentStart(const YAML::Mark&) override {}
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override { Value(nullptr, YAML::Mark()); }
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override { Value(nullptr, YAML::Mark()); }
  void OnScalar(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                const std::string& value) override {
    Value(&value, mark);
  }
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {
    Value(nullptr, YAML::Mark());
    stack_.push_back(Level{false, true, {}});
  }
  void OnSequenceEnd() override { stack_.pop_back(); }
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {
    Value(nullptr, YAML::Mark());
    stack_.push_back(Level{true, true, {}});
  }
  void OnMapEnd() override { stack_.pop_back(); }

 private:
  struct Level {
    bool map = false;
    bool expect_key = true;  // maps: the next node is a key
    std::map<std::string, int> key_lines;
  };

  // One node starts in the current container: a key or a value in a map.
  // Only scalar keys are compared (the project's files have no others).
  void Value(const std::string* scalar, const YAML::Mark& mark) {
    if (stack_.empty() || !stack_.back().map) return;
    Level& level = stack_.back();
    const bool is_key = level.expect_key;
    level.expect_key = !level.expect_key;
    if (!is_key || scalar == nullptr || !error_.empty()) return;
    const int line = mark.is_null() ? 0 : mark.line + 1;
    const auto [it, inserted] = level.key_lines.emplace(*scalar, line);
    if (!inserted) {
      error_ = file_ + ":" + std::to_string(line) + ": duplicated key '" + *scalar +
               "' (first at line " + std::to_string(it->second) + ")";
    }
  }

  std::string file_;
  std::vector<Level> stack_;
  std::string error_;
};

}  // namespace

std::string FindDuplicateKey(const std::string& yaml_text, const std::string& name) {
  DuplicateKeyFinder finder(name);
  std::istringstream in(yaml_text);
  YAML::Parser parser(in);
  // The first document only: the one YAML::Load reads.
  parser.HandleNextDocument(finder);
  return finder.error();
}

void YamlReader::Fail(const YAML::Node& near, const std::string& key,
                      const std::string& what) const {
  std::ostringstream s;
  s << file_;
  if (near.IsDefined() && !near.Mark().is_null()) s << ":" << near.Mark().line + 1;
  s << ": " << key << ": " << what;
  throw YamlError(s.str());
}

void YamlReader::ExpectMap(const YAML::Node& node, const std::string& key) const {
  if (!node.IsMap()) Fail(node, key, "expected a mapping of keys, got " + Kind(node));
}

void YamlReader::ExpectSequence(const YAML::Node& node, const std::string& key) const {
  if (!node.IsSequence()) Fail(node, key, "expected a list, got " + Kind(node));
}

void YamlReader::OnlyKeys(const YAML::Node& map, const std::string& key,
                          std::initializer_list<const char*> allowed) const {
  for (const auto& kv : map) {
    const std::string name = kv.first.as<std::string>();
    bool known = false;
    for (const char* a : allowed) known = known || name == a;
    if (!known) Fail(kv.first, Join(key, name), "unknown key");
  }
}

YAML::Node YamlReader::Required(const YAML::Node& map, const std::string& key,
                                const std::string& name) const {
  YAML::Node child = map[name];
  if (!child.IsDefined() || child.IsNull()) Fail(map, Join(key, name), "missing key");
  return child;
}

double YamlReader::Double(const YAML::Node& node, const std::string& key) const {
  if (!node.IsScalar()) Fail(node, key, "expected a number, got " + Kind(node));
  double value = 0.0;
  if (!YAML::convert<double>::decode(node, value)) {
    Fail(node, key, "expected a number, got '" + node.Scalar() + "'");
  }
  if (!std::isfinite(value)) Fail(node, key, "must be a finite number");
  return value;
}

double YamlReader::Positive(const YAML::Node& node, const std::string& key) const {
  const double value = Double(node, key);
  if (value <= 0.0) Fail(node, key, "must be positive");
  return value;
}

int YamlReader::Int(const YAML::Node& node, const std::string& key) const {
  if (!node.IsScalar()) Fail(node, key, "expected an integer, got " + Kind(node));
  int value = 0;
  if (!YAML::convert<int>::decode(node, value)) {
    Fail(node, key, "expected an integer, got '" + node.Scalar() + "'");
  }
  return value;
}

bool YamlReader::Bool(const YAML::Node& node, const std::string& key) const {
  bool value = false;
  if (!node.IsScalar() || !YAML::convert<bool>::decode(node, value)) {
    Fail(node, key, "expected true or false");
  }
  return value;
}

std::string YamlReader::String(const YAML::Node& node, const std::string& key) const {
  if (!node.IsScalar()) Fail(node, key, "expected a string, got " + Kind(node));
  return node.Scalar();
}

std::string YamlReader::Join(const std::string& key, const std::string& name) {
  return key.empty() ? name : key + "." + name;
}

std::string YamlReader::Index(const std::string& key, size_t i) {
  return key + "[" + std::to_string(i) + "]";
}

std::string YamlReader::Kind(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Map:
      return "a mapping";
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Scalar:
      return "'" + node.Scalar() + "'";
    default:
      return "nothing";
  }
}

bool ParseYamlDocument(const std::string& yaml_text, const std::string& name,
                       const std::function<void(const YamlReader&, const YAML::Node&)>& parse,
                       std::string* error) {
  const YamlReader r(name);
  try {
    YAML::Node root;
    try {
      root = YAML::Load(yaml_text);
    } catch (const YAML::Exception& e) {
      std::ostringstream s;
      s << name << ":" << e.mark.line + 1 << ": YAML syntax: " << e.msg;
      throw YamlError(s.str());
    }
    const std::string duplicate = FindDuplicateKey(yaml_text, name);
    if (!duplicate.empty()) throw YamlError(duplicate);
    if (!root.IsMap()) r.Fail(root, "(document)", "expected a mapping of keys at the top level");
    parse(r, root);
  } catch (const YamlError& e) {
    if (error != nullptr) *error = e.what();
    return false;
  } catch (const YAML::Exception& e) {
    // A value of the wrong shape that a typed read did not anticipate.
    if (error != nullptr) *error = name + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg;
    return false;
  }
  return true;
}

}  // namespace roomfix
