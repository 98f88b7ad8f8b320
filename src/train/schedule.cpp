#include "train/schedule.h"

#include <cmath>
#include <string>

namespace ddhgs::train {

using nlohmann::json;

namespace {

struct Renamed {
  const char* section;
  const char* absolute;  // format_version 1 key, in iterations
  const char* fraction;  // today's key, a fraction of `iterations`
};

constexpr Renamed kRenamed[] = {
    {"model", "sh_degree_every", "sh_degree_every_fraction"},
    {"optim", "means_lr_max_steps", "means_lr_decay_fraction"},
    {"densify", "from_iter", "from_fraction"},
    {"densify", "until_iter", "until_fraction"},
    {"densify", "opacity_reset_every", "opacity_reset_every_fraction"},
};

int64_t of_run(double fraction, int64_t iterations) {
  return std::llround(fraction * double(iterations));
}

// An interval: never shorter than one iteration unless switched off.
int64_t interval(double fraction, int64_t iterations) {
  return fraction > 0 ? std::max<int64_t>(1, of_run(fraction, iterations)) : 0;
}

}  // namespace

Schedule schedule_from_config(const json& config) {
  Schedule s;
  s.iterations = config.at("iterations").get<int64_t>();
  const json& model = config.at("model");
  const json& densify = config.at("densify");
  s.sh_degree_every = interval(model.at("sh_degree_every_fraction").get<double>(), s.iterations);
  s.means_lr_decay_steps =
      interval(config.at("optim").at("means_lr_decay_fraction").get<double>(), s.iterations);
  s.densify_from = of_run(densify.at("from_fraction").get<double>(), s.iterations);
  s.densify_until = of_run(densify.at("until_fraction").get<double>(), s.iterations);
  s.densify_every = densify.at("every").get<int64_t>();
  s.opacity_reset_every =
      interval(densify.at("opacity_reset_every_fraction").get<double>(), s.iterations);
  return s;
}

bool upgrade_absolute_schedule(json& config, int64_t iterations) {
  if (!config.is_object()) return false;
  const double n = double(iterations);
  bool changed = false;
  for (const Renamed& r : kRenamed) {
    if (!config.contains(r.section) || !config[r.section].is_object()) continue;
    json& section = config[r.section];
    if (!section.contains(r.absolute)) continue;
    const json value = section[r.absolute];
    section.erase(r.absolute);
    // A value that is not a number is left for validation to report.
    section[r.fraction] = !value.is_number() ? value : json(n > 0 ? value.get<double>() / n : 0.0);
    changed = true;
  }
  return changed;
}

}  // namespace ddhgs::train
