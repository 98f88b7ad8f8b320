#include "core/band_map.h"

#include <algorithm>
#include <charconv>
#include <cmath>

#include "core/error.h"
#include "core/log.h"
#include "core/text.h"

namespace ddhgs::core {
namespace {

std::string nm(double value) {
  return format_g(value) + " nm";
}

double parse_number(const std::string& word, const std::string& option) {
  double value = 0;
  size_t first = word.find_first_not_of(' '), last = word.find_last_not_of(' ');
  const std::string trimmed =
      first == std::string::npos ? "" : word.substr(first, last - first + 1);
  auto [end, error] = std::from_chars(trimmed.data(), trimmed.data() + trimmed.size(), value);
  if (trimmed.empty() || error != std::errc() || end != trimmed.data() + trimmed.size() ||
      !std::isfinite(value))
    throw Error(option + ": " + quoted_value(word) + " is not a number");
  return value;
}

// Interpolation weights of one wavelength over increasing from_nm: adds
// `scale` times them into row[0..N).
void add_interpolated(const std::vector<double>& from_nm, double wavelength, double scale,
                      double* row) {
  const size_t n = from_nm.size();
  if (n == 1) {
    row[0] += scale;
    return;
  }
  size_t hi =
      size_t(std::upper_bound(from_nm.begin(), from_nm.end(), wavelength) - from_nm.begin());
  hi = std::clamp<size_t>(hi, 1, n - 1);
  const size_t lo = hi - 1;
  const double t = (wavelength - from_nm[lo]) / (from_nm[hi] - from_nm[lo]);
  row[lo] += scale * (1 - t);
  row[hi] += scale * t;
}

void require_increasing(const std::vector<double>& from_nm) {
  require(!from_nm.empty(), "band map: the model has no wavelengths");
  for (size_t i = 1; i < from_nm.size(); ++i)
    require(from_nm[i] > from_nm[i - 1],
            "band map: the model's wavelengths must increase (band " + std::to_string(i) + ")");
}

}  // namespace

torch::Tensor selection_map(int64_t bands, const std::vector<int64_t>& rows) {
  torch::Tensor map = torch::zeros({int64_t(rows.size()), bands}, torch::kFloat64);
  double* m = map.data_ptr<double>();
  for (size_t j = 0; j < rows.size(); ++j) m[int64_t(j) * bands + rows[j]] = 1.0;
  return map;
}

torch::Tensor interpolation_map(const std::vector<double>& from_nm,
                                const std::vector<double>& to_nm) {
  require_increasing(from_nm);
  require(!to_nm.empty(), "band map: no wavelengths to render");
  const double lo = from_nm.front(), hi = from_nm.back();
  auto map = torch::zeros({int64_t(to_nm.size()), int64_t(from_nm.size())}, torch::kFloat64);
  double* data = map.data_ptr<double>();
  for (size_t m = 0; m < to_nm.size(); ++m) {
    const double w = to_nm[m];
    const double slack = 1e-9 * std::max(1.0, hi - lo);
    if (w < lo - slack || w > hi + slack)
      throw Error("wavelength " + nm(w) + " is outside the model's bands (" + nm(lo) + " to " +
                  nm(hi) + "); ddhgs interpolates between captured bands, it does not " +
                  "extrapolate");
    add_interpolated(from_nm, std::clamp(w, lo, hi), 1.0, data + m * from_nm.size());
  }
  return map;
}

std::vector<double> parse_wavelength_list(const std::string& text, const std::string& option) {
  const bool range = text.find(':') != std::string::npos;
  // Every item between separators, each a number.
  std::vector<double> items;
  for (size_t at = 0;;) {
    const size_t end = text.find(range ? ':' : ',', at);
    items.push_back(parse_number(text.substr(at, end - at), option));
    if (end == std::string::npos) break;
    at = end + 1;
  }
  if (!range) return items;
  if (items.size() != 3)
    throw Error(option + ": " + quoted_value(text) +
                " must be START:STOP:STEP (nm), e.g. 450:950:5");
  const double start = items[0], stop = items[1], step = items[2];
  if (!(step > 0) || stop < start)
    throw Error(option + ": " + quoted_value(text) + " needs STOP >= START and a positive STEP");
  const double count = std::floor((stop - start) / step + 1e-9) + 1;
  if (count > 100000)
    throw Error(option + ": " + quoted_value(text) + " asks for over 100,000 wavelengths");
  std::vector<double> out;
  for (int64_t i = 0; i < int64_t(count); ++i) out.push_back(start + double(i) * step);
  return out;
}

std::vector<double> trapezoid_weights(const std::vector<double>& wavelengths_nm) {
  const size_t s = wavelengths_nm.size();
  std::vector<double> w(s, 0.0);
  if (s == 1) w[0] = 1;
  for (size_t i = 0; i + 1 < s; ++i) {
    const double half = 0.5 * (wavelengths_nm[i + 1] - wavelengths_nm[i]);
    w[i] += half;
    w[i + 1] += half;
  }
  return w;
}

ResponseMap response_map(const ResponseFunctions& response, const std::vector<double>& from_nm) {
  require_increasing(from_nm);
  const int64_t S = int64_t(response.wavelengths_nm.size()), C = response.values.size(1);
  const int64_t N = int64_t(from_nm.size());
  const std::vector<double> weights = trapezoid_weights(response.wavelengths_nm);
  const auto values = response.values.to(torch::kFloat64).contiguous();
  const double* r = values.data_ptr<double>();
  ResponseMap out;
  out.map = torch::zeros({C, N}, torch::kFloat64);
  double* map = out.map.data_ptr<double>();
  const double lo = from_nm.front(), hi = from_nm.back();
  for (int64_t c = 0; c < C; ++c) {
    double inside = 0, total = 0, centre = 0;
    for (int64_t s = 0; s < S; ++s) {
      const double w = weights[size_t(s)] * r[s * C + c];
      const double wavelength = response.wavelengths_nm[size_t(s)];
      total += w;
      if (wavelength < lo || wavelength > hi) continue;
      inside += w;
      centre += w * wavelength;
      add_interpolated(from_nm, wavelength, w, map + c * N);
    }
    if (!(inside > 0))
      throw Error("response " + quoted_value(response.channels[size_t(c)]) +
                  " has no response between " + nm(lo) + " and " + nm(hi) + ", the model's bands");
    for (int64_t n = 0; n < N; ++n) map[c * N + n] /= inside;
    out.centres_nm.push_back(centre / inside);
    out.captured.push_back(inside / total);
  }
  return out;
}

}  // namespace ddhgs::core
