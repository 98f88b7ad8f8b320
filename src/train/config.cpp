#include "train/config.h"

#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <set>

#include "core/error.h"
#include "core/log.h"
#include "io/files/atomic_file.h"
#include "train/schedule.h"

namespace ddhgs::train {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Keys whose value may be one number or a list of numbers (one per band).
const std::set<std::string> kNumberOrList = {"model.background"};

json parse_json_file(const fs::path& path) {
  std::string text = io::read_file(path);
  try {
    return json::parse(text);
  } catch (const json::exception& e) {
    // parse_error, and out_of_range for a number no double holds.
    throw core::Error(path, "not valid JSON (" + core::message_of(e) + ")");
  }
}

std::string type_name(const json& v) {
  if (v.is_number_integer()) return "an integer";
  if (v.is_number()) return "a number";
  if (v.is_boolean()) return "true or false";
  if (v.is_string()) return "a string";
  if (v.is_array()) return "a list";
  if (v.is_object()) return "an object";
  return "null";
}

bool is_number_list(const json& v) {
  if (!v.is_array()) return false;
  for (const auto& x : v)
    if (!x.is_number()) return false;
  return true;
}

void check_value(const json& schema, const json& value, const std::string& key,
                 const std::string& source) {
  if (kNumberOrList.count(key)) {
    if (value.is_number() || is_number_list(value)) return;
    throw core::Error(source, "key '" + key + "' must be a number or a list of numbers");
  }
  bool ok = false;
  if (schema.is_object()) {
    ok = value.is_object();
  } else if (schema.is_number_integer()) {
    ok = value.is_number_integer();
  } else if (schema.is_number()) {
    ok = value.is_number();
  } else if (schema.is_boolean()) {
    ok = value.is_boolean();
  } else if (schema.is_string()) {
    ok = value.is_string();
  } else if (schema.is_array()) {
    ok = is_number_list(value);
  }
  if (!ok)
    throw core::Error(
        source, "key '" + key + "' must be " + type_name(schema) + ", got " + type_name(value));
}

// Checks every key of `config` against `schema`; complete requires all keys.
void check_object(const json& schema, const json& config, const std::string& prefix,
                  const std::string& source, bool complete) {
  for (const auto& [key, value] : config.items()) {
    const std::string path = prefix.empty() ? key : prefix + "." + key;
    if (prefix.empty() && (key == "extends" || key == "format_version")) continue;
    if (!schema.contains(key)) throw core::Error(source, "unknown key '" + path + "'");
    check_value(schema.at(key), value, path, source);
    if (schema.at(key).is_object()) check_object(schema.at(key), value, path, source, complete);
  }
  if (!complete) return;
  for (const auto& [key, value] : schema.items()) {
    const std::string path = prefix.empty() ? key : prefix + "." + key;
    if (!config.contains(key)) throw core::Error(source, "missing key '" + path + "'");
  }
}

void check_version(const json& config, const std::string& source) {
  if (!config.contains("format_version") || !config["format_version"].is_number_integer())
    throw core::Error(source, "missing integer key 'format_version'");
  int version = config["format_version"].get<int>();
  // No converters: ddhgs has not been released, so a file of another version
  // is refused rather than read with guessed values.
  if (version != kConfigFormatVersion)
    throw core::Error(source, "written for config format_version " + std::to_string(version) +
                                  "; this ddhgs reads format_version " +
                                  std::to_string(kConfigFormatVersion) +
                                  " only (rewrite the file from configs/, or retrain)");
}

fs::path preset_path(const std::string& name_or_path, const fs::path& relative_to) {
  fs::path p(name_or_path);
  if (p.extension() == ".json") return p.is_absolute() ? p : relative_to / p;
  return config_dir() / (name_or_path + ".json");
}

const json& schema() {
  static const json s = [] {
    fs::path path = config_dir() / "default.json";
    json j = parse_json_file(path);
    check_version(j, path.string());
    return j;
  }();
  return s;
}

json load_chain(const fs::path& path, int depth) {
  if (depth > 16) throw core::Error(path, "'extends' chain is too long (a cycle?)");
  if (!fs::exists(path)) throw core::Error(path, "no such preset");
  json j = parse_json_file(path);
  if (!j.is_object()) throw core::Error(path, "expected a JSON object");
  check_version(j, path.string());
  json base = schema();
  if (j.contains("extends")) {
    if (!j["extends"].is_string()) throw core::Error(path, "'extends' must be a preset name");
    base = load_chain(preset_path(j["extends"].get<std::string>(), path.parent_path()), depth + 1);
  }
  check_object(schema(), j, "", path.string(), false);
  j.erase("extends");
  base.merge_patch(j);
  return base;
}

}  // namespace

fs::path config_dir() {
  if (const char* env = std::getenv("DDHGS_CONFIG_DIR"))
    if (*env) return fs::path(env);
  std::error_code ec;
  fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec)
    for (fs::path dir = exe.parent_path(); !dir.empty(); dir = dir.parent_path()) {
      if (fs::exists(dir / "configs" / "default.json")) return dir / "configs";
      if (fs::exists(dir / "share" / "ddhgs" / "configs" / "default.json"))
        return dir / "share" / "ddhgs" / "configs";
      if (dir == dir.root_path()) break;
    }
  return "/usr/share/ddhgs/configs";
}

json load_preset(const std::string& name_or_path) {
  fs::path path = preset_path(name_or_path, fs::current_path());
  if (!fs::exists(path))
    throw core::Error(path, "no such preset (presets live in " + config_dir().string() + ")");
  json config = load_chain(path, 0);
  validate_config(config, path.string());
  return config;
}

void validate_config(const json& config, const std::string& source) {
  if (!config.is_object()) throw core::Error(source, "expected a JSON object");
  check_version(config, source);
  if (config.contains("extends")) throw core::Error(source, "a resolved config has no 'extends'");
  check_object(schema(), config, "", source, true);
  check_config_values(config, source);
}

void set_key(json& config, const std::string& key_path, const std::string& value,
             const std::string& source) {
  json parsed;
  try {
    parsed = json::parse(value);
  } catch (const json::parse_error&) {
    parsed = value;
  } catch (const json::out_of_range&) {  // "1e999": a number no double holds
    throw core::Error(source, "key '" + key_path + "' is " + value + ", too large a number");
  }
  const json* s = &schema();
  json* target = &config;
  size_t start = 0;
  while (true) {
    size_t dot = key_path.find('.', start);
    std::string key = key_path.substr(start, dot == std::string::npos ? dot : dot - start);
    std::string so_far = key_path.substr(0, dot);
    if (!s->is_object() || !s->contains(key) || (so_far == "format_version"))
      throw core::Error(source, "unknown key '" + key_path + "'");
    s = &s->at(key);
    target = &(*target)[key];
    if (dot == std::string::npos) break;
    start = dot + 1;
  }
  if (s->is_object()) throw core::Error(source, "key '" + key_path + "' is a section, not a value");
  check_value(*s, parsed, key_path, source);
  check_config_value(key_path, parsed, source);
  *target = parsed;
}

void apply_assignment(json& config, const std::string& assignment) {
  size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw core::Error("--set", "expected key.path=value, got '" + assignment + "'");
  set_key(config, assignment.substr(0, eq), assignment.substr(eq + 1));
}

}  // namespace ddhgs::train
