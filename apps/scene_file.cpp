#include "apps/scene_file.hpp"

#include <yaml-cpp/yaml.h>

#include <map>
#include <stdexcept>

namespace cellfsi::app {

namespace {

std::string where(const std::string& path, const YAML::Mark& m) {
  return "scene file '" + path + "'" + (m.is_null() ? "" : ", line " + std::to_string(m.line + 1));
}

/// Refuses a key that a map repeats, in `node` and every map below it; `prefix` names the enclosing keys.
void check_unique_keys(const std::string& path, const YAML::Node& node, const std::string& prefix) {
  if (!node.IsMap()) return;
  std::map<std::string, int> first_line;
  for (auto it = node.begin(); it != node.end(); ++it) {
    const std::string key = it->first.Scalar();
    const YAML::Mark m = it->first.Mark();
    const auto [pos, fresh] = first_line.emplace(key, m.line + 1);
    if (!fresh)
      throw std::invalid_argument(where(path, m) + ": key '" + prefix + key +
                                  "' appears twice (first on line " + std::to_string(pos->second) +
                                  "); give each option once");
    check_unique_keys(path, it->second, prefix + key + ".");
  }
}

/// The line of every option the file sets (flattened names, without '-').
void option_lines(const YAML::Node& node, const std::string& prefix, std::map<std::string, int>& out) {
  if (!node.IsMap()) return;
  for (auto it = node.begin(); it != node.end(); ++it) {
    const std::string name = prefix + it->first.Scalar();
    if (it->second.IsMap())
      option_lines(it->second, name + "_", out);
    else
      out[name] = it->first.Mark().line + 1;
  }
}

}  // namespace

std::string with_scene_file_line(const std::string& message, const std::string& path,
                                 const std::vector<std::string>& command_line) {
  const std::string head = "option -";
  if (path.empty() || message.rfind(head, 0) != 0) return message;
  const std::size_t end = message.find_first_of(" =", head.size());
  const std::string name = message.substr(head.size(), end - head.size());
  for (const std::string& arg : command_line)
    if (arg == "-" + name) return message;  // the command line's value
  std::map<std::string, int> lines;
  try {
    option_lines(YAML::LoadFile(path), "", lines);
  } catch (const YAML::Exception&) {
    return message;
  }
  const auto it = lines.find(name);
  if (it == lines.end()) return message;
  return message + " (scene file '" + path + "', line " + std::to_string(it->second) + ")";
}

void check_scene_file(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw std::invalid_argument("scene file '" + path + "' cannot be read");
  } catch (const YAML::Exception& e) {
    std::string msg = e.msg;
    for (char& c : msg)
      if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = '?';  // binary
    throw std::invalid_argument(where(path, e.mark) + ": " + msg + " (not valid YAML)");
  }
  if (root.IsNull() || (root.IsMap() && root.size() == 0))
    throw std::invalid_argument("scene file '" + path + "' is empty: it sets no option (see scenes/*.yaml)");
  if (!root.IsMap())
    throw std::invalid_argument(where(path, root.Mark()) + ": the top level must be a map of options " +
                                "(key: value), not " + (root.IsSequence() ? "a list" : "a single value"));
  check_unique_keys(path, root, "");
}

}  // namespace cellfsi::app
