#include "train/schedule.h"

#include <cmath>
#include <string>

namespace ddhgs::train {

using nlohmann::json;

namespace {

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

}  // namespace ddhgs::train
