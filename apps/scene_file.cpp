#include "apps/scene_file.hpp"

#include <yaml-cpp/yaml.h>

#include <cctype>
#include <map>
#include <stdexcept>
#include <utility>

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

/// Calls visit(name, value node) for every option the file sets (flattened names, without '-'), in the
/// file's order.
template <class Visit>
void for_each_option(const YAML::Node& node, const std::string& prefix, Visit&& visit) {
  if (!node.IsMap()) return;
  for (auto it = node.begin(); it != node.end(); ++it) {
    const std::string name = prefix + it->first.Scalar();
    if (it->second.IsMap())
      for_each_option(it->second, name + "_", visit);
    else
      visit(name, it->first, it->second);
  }
}

/// The line of every option the file sets (flattened names, without '-').
void option_lines(const YAML::Node& node, std::map<std::string, int>& out) {
  for_each_option(node, "", [&](const std::string& name, const YAML::Node& key, const YAML::Node&) {
    out[name] = key.Mark().line + 1;
  });
}

/// An option name on the command line: '-' and a letter (a value may be a negative number).
bool is_option_word(const std::string& w) {
  return w.size() > 1 && w[0] == '-' && std::isalpha(static_cast<unsigned char>(w[1]));
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
    option_lines(YAML::LoadFile(path), lines);
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

std::string given_options_yaml(const std::string& path, const std::vector<std::string>& command_line,
                               const std::string& scene_name) {
  // In order of first appearance; a later source replaces the value in place.
  std::vector<std::pair<std::string, std::string>> options;
  auto set = [&options](const std::string& name, const std::string& value) {
    static const char* const kNotRecorded[] = {"restart", "help", "solid_ranks"};
    for (const char* k : kNotRecorded)
      if (name == k) return;
    for (auto& [k, v] : options)
      if (k == name) {
        v = value;
        return;
      }
    options.emplace_back(name, value);
  };
  if (!path.empty()) {
    for_each_option(YAML::LoadFile(path), "", [&](const std::string& name, const YAML::Node&,
                                                  const YAML::Node& value) {
      // A list is read by PETSc as its items joined by commas.
      std::string text;
      if (value.IsSequence())
        for (std::size_t i = 0; i < value.size(); ++i) {
          if (i) text += ',';
          text += value[i].as<std::string>();  // (appended apart: GCC 12 warns, wrongly, on "," + string)
        }
      else if (!value.IsNull())
        text = value.as<std::string>();
      set(name, text);
    });
  }
  // The command line: after argv[0] and the scene file (a first argument that is not an option).
  std::size_t i = command_line.size() > 1 && !is_option_word(command_line[1]) ? 2 : 1;
  for (; i < command_line.size(); ++i) {
    if (!is_option_word(command_line[i])) continue;
    const bool has_value = i + 1 < command_line.size() && !is_option_word(command_line[i + 1]);
    set(command_line[i].substr(1), has_value ? command_line[i + 1] : std::string());
    if (has_value) ++i;
  }
  bool named = false;
  for (const auto& kv : options) named = named || kv.first == "scene";
  if (!named) options.emplace_back("scene", scene_name);

  YAML::Emitter out;
  out << YAML::Comment("the options this run was given (scene file, then command line); run it again with: "
                       "cellfsi options.yaml [-output_dir DIR]")
      << YAML::Newline << YAML::BeginMap;
  for (const auto& [k, v] : options) out << YAML::Key << k << YAML::Value << v;
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace cellfsi::app
