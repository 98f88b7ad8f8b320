// Training configuration: versioned JSON presets under configs/, resolved
// into one complete JSON object (every key) that a run folder keeps.
//
// configs/default.json is the schema: every key a preset, an override or a
// run's config.json sets must exist there with a compatible type. A preset
// may "extends" another one (by name or path); keys it sets replace the
// parent's. A key added to default.json gets a row in kAddedKeys
// (config.cpp): the value under which older run folders keep training as they did.
#pragma once
#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace ddhgs::train {

// 2: schedule keys are fractions of `iterations` (train/schedule.h). A file
// of another version is refused with one line naming both versions.
constexpr int kConfigFormatVersion = 2;

// A preset by name ("demo": demo.json where train/preset_lookup.h finds it,
// else the built-in one) or by path to a .json file, with its "extends"
// chain resolved and every key validated. The result has every key of
// default.json and no "extends".
nlohmann::json load_preset(const std::string& name_or_path);

// Validates a resolved config (e.g. a run's config.json) read from `source`.
void validate_config(const nlohmann::json& config, const std::string& source);

// Brings a run's config.json written by an earlier ddhgs of this
// format_version up to today's keys: each key added since then that it lacks
// gets the value that reproduces how that ddhgs trained (loss.view_fraction 1:
// whole views; model.spectral_rank 0: per band; ...), not today's default, so
// an old run resumes, evaluates and renders as it was trained. Keys since
// removed are dropped when they cannot matter. Returns "key=value" for each
// key filled or dropped (empty when the config was current); core::Error
// naming `source` when a removed key mattered. Keys that were never in the
// format (typos), and a config of another format_version, are left for
// validate_config to refuse.
std::vector<std::string> fill_added_keys(nlohmann::json& config, const std::string& source);

// core::Error naming source and the key when a number is outside what the
// key allows (train/config_values.cpp): iterations >= 1, sh_degree 0..3,
// learning rates >= 0, divisors > 0, ...; and the rules across keys: some
// loss, a band range that keeps a band, a rising noise schedule. Part of
// validate_config.
void check_config_values(const nlohmann::json& config, const std::string& source);
// Whether a numeric key has a range (every one should: a test checks).
bool has_range(const std::string& key);
// The same for one key (dotted path) about to be set to value.
void check_config_value(const std::string& key, const nlohmann::json& value,
                        const std::string& source);

// Sets one key ("densify.grad_threshold") from text: JSON if it parses as
// JSON, else a string. Throws core::Error naming `source` and the key when
// the key is unknown or the value has the wrong type.
void set_key(nlohmann::json& config, const std::string& key_path, const std::string& value,
             const std::string& source = "--set");

// "key.path=value" -> set_key.
void apply_assignment(nlohmann::json& config, const std::string& assignment);

}  // namespace ddhgs::train
