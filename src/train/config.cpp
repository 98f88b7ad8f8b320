#include "train/config.h"

#include <set>

#include "core/error.h"
#include "core/text.h"
#include "train/preset_lookup.h"
#include "train/schedule.h"

namespace ddhgs::train {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Keys whose value may be one number or a list of numbers (one per band).
const std::set<std::string> kNumberOrList = {"model.background"};

json parse_preset(const PresetText& preset) {
  try {
    return json::parse(preset.text);
  } catch (const json::exception& e) {
    // parse_error, and out_of_range for a number no double holds.
    throw core::Error(preset.source, "not valid JSON (" + core::message_of(e) + ")");
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
  // No converters between versions: a file of another version is refused
  // rather than read with guessed values (keys added within a version:
  // fill_added_keys).
  if (version != kConfigFormatVersion)
    throw core::Error(source, "written for config format_version " + std::to_string(version) +
                                  "; this ddhgs reads format_version " +
                                  std::to_string(kConfigFormatVersion) +
                                  " only (rewrite the file from configs/, or retrain)");
}

// A preset by name (looked up: train/preset_lookup.h) or by a .json path
// relative to `relative_to`.
PresetText locate(const std::string& name_or_path, const fs::path& relative_to) {
  const fs::path p(name_or_path);
  if (p.extension() == ".json") return read_preset_file(p.is_absolute() ? p : relative_to / p);
  return find_preset(name_or_path);
}

const json& schema() {
  static const json s = [] {
    const PresetText preset = find_preset("default");
    json j = parse_preset(preset);
    check_version(j, preset.source);
    return j;
  }();
  return s;
}

json load_chain(const PresetText& preset, int depth) {
  const std::string& source = preset.source;
  if (depth > 16) throw core::Error(source, "'extends' chain is too long (a cycle?)");
  json j = parse_preset(preset);
  if (!j.is_object()) throw core::Error(source, "expected a JSON object");
  check_version(j, source);
  json base = schema();
  if (j.contains("extends")) {
    if (!j["extends"].is_string()) throw core::Error(source, "'extends' must be a preset name");
    base = load_chain(locate(j["extends"].get<std::string>(), preset.directory), depth + 1);
  }
  check_object(schema(), j, "", source, false);
  j.erase("extends");
  base.merge_patch(j);
  return base;
}

}  // namespace

json load_preset(const std::string& name_or_path) {
  const PresetText preset = locate(name_or_path, fs::current_path());
  json config = load_chain(preset, 0);
  validate_config(config, preset.source);
  return config;
}

namespace {

// Keys added to configs/default.json after format_version 2 began (7616d39),
// oldest first, each with the value under which a config written before it
// trains as it did then. A key that only matters when another, older key
// switches its feature on gets today's default (it cannot act). A test reads a
// config.json from the first version 2 through read_run_config: adding a key
// to default.json without a row here fails it.
struct AddedKey {
  const char* key;
  const char* value;  // JSON
};
constexpr AddedKey kAddedKeys[] = {
    {"model.background_from_views", "false"},
    {"camera_refinement.enabled", "false"},
    {"camera_refinement.rotation_lr", "0.0001"},     // refinement off
    {"camera_refinement.translation_lr", "0.0001"},  // refinement off
    {"camera_refinement.rig", "false"},
    {"camera_refinement.rig_rotation_lr", "0.0005"},  // rig refinement off
    {"camera_refinement.rig_offset_lr", "0.0005"},    // rig refinement off
    {"camera_refinement.rig_pull", "0.00001"},        // rig refinement off
    {"init.extra_random_per_pixel", "0"},             // acts at initialisation only
    {"model.spectral_rank", "0"},                     // one SH set per band
    {"optim.basis_lr", "0.001"},                      // per band: no basis
    {"data.band_step", "1"},
    {"optim.latent_sh_lr_scale", "1"},
    {"model.subspace_from_bands", "0"},  // rank -1 took the signal rank at any band count
    {"output.test_every", "0"},
    {"diffusion.joint", "true"},
    {"diffusion.pairs", "\"training\""},
    {"diffusion.folds", "4"},              // pairs "training"
    {"diffusion.fold_iterations", "0.5"},  // pairs "training"
    {"diffusion.distill_steps", "0"},
    {"diffusion.distill_weight", "0.5"},  // no distillation
    {"diffusion.distill_every", "2"},     // no distillation
    {"diffusion.validation_every", "0"},
    {"diffusion.perturb_px", "2.0"},  // pairs "training"
    {"loss.bands_per_step", "0"},
    {"loss.bands_per_step_until_fraction", "1"},  // bands were drawn for the whole run
    {"loss.view_fraction", "1"},
    {"loss.view_fraction_until_fraction", "1"},
    {"loss.view_fraction_from_pixels", "0"},  // every view was cropped at view_fraction
    {"optim.lr_decay_from_fraction", "0.9"},  // rates were constant
    {"optim.lr_final_scale", "1"},
    {"model.exposure_correction", "\"off\""},
    {"optim.exposure_lr", "0.01"},    // correction off
    {"loss.exposure_prior", "0.01"},  // correction off
    {"optim.iterations_per_band_view", "0"},
    {"camera_refinement.rig_warmup_fraction", "0"},  // rig runs had no warm-up
    {"diffusion.prior", "\"\""},
    {"diffusion.prior_finetune_steps", "0"},
    {"camera_refinement.rig_align_fraction", "0"},  // rig runs had no alignment phase
    {"camera_refinement.rig_pivot", "false"},       // turns about the camera centre
    {"camera_refinement.rig_start", "\"\""},        // the factory values
    {"data.block_as_flight", "false"},              // blocks trained on their own schedule
};

// The one section added whole since format_version 2 began.
constexpr const char* kAddedSection = "camera_refinement";

json* find_key(json& config, const std::string& key_path, bool create) {
  json* at = &config;
  for (size_t start = 0;;) {
    const size_t dot = key_path.find('.', start);
    const std::string key = key_path.substr(start, dot == std::string::npos ? dot : dot - start);
    if (create && at->is_null()) *at = json::object();
    if (!at->is_object() || (!create && !at->contains(key))) return nullptr;
    at = &(*at)[key];
    if (dot == std::string::npos) return at;
    start = dot + 1;
  }
}

}  // namespace

std::vector<std::string> fill_added_keys(json& config, const std::string& source) {
  std::vector<std::string> changed;
  // Another format_version, or no object: validate_config names the problem.
  if (!config.is_object() || config.value("format_version", json()) != kConfigFormatVersion)
    return changed;
  for (const AddedKey& added : kAddedKeys) {
    const std::string key = added.key;
    const std::string section = key.substr(0, key.find('.'));
    // A section the file lacks altogether is not an earlier version's (they
    // all had it), unless the section itself was added since.
    if (section != kAddedSection && (!config.contains(section) || !config[section].is_object()))
      continue;
    if (find_key(config, key, false)) continue;
    *find_key(config, key, true) = json::parse(added.value);
    changed.push_back(key + "=" + added.value);
  }
  // Removed keys. init.extra_random_points (20,000 random Gaussians, before
  // init.extra_random_per_pixel) acted only at initialisation.
  if (json* init = find_key(config, "init", false);
      init && init->is_object() && init->contains("extra_random_points")) {
    init->erase("extra_random_points");
    changed.push_back("init.extra_random_points removed");
  }
  if (json* d = find_key(config, "diffusion", false);
      d && d->is_object() && d->contains("perturb_degrees")) {
    if (d->contains("pairs") && (*d)["pairs"] == "perturbed")
      throw core::Error(source,
                        "diffusion.perturb_degrees is from an earlier ddhgs; the turned "
                        "cameras' turn is now diffusion.perturb_px (pixels): replace it");
    d->erase("perturb_degrees");
    changed.push_back("diffusion.perturb_degrees removed");
  }
  return changed;
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
    throw core::Error(
        source, "key '" + key_path + "' is " + core::quoted_value(value) + ", too large a number");
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
    throw core::Error("--set", "expected key.path=value, got " + core::quoted_value(assignment));
  set_key(config, assignment.substr(0, eq), assignment.substr(eq + 1));
}

}  // namespace ddhgs::train
