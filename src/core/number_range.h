// How large a number read from a model file or a response CSV may be.
#pragma once
#include <cmath>

namespace ddhgs::core {

// The largest magnitude accepted: the product of two such numbers (a basis
// row times a latent value, a response times a band) stays finite in
// float32, whose largest value is 3.4e38 (sqrt: 1.8e19). A value past it
// renders as Inf or NaN rather than failing where it is read.
constexpr double kMaxFileNumber = 1e18;

// Finite and at most kMaxFileNumber in magnitude.
inline bool renderable_number(double value) {
  return std::abs(value) <= kMaxFileNumber;  // false for NaN
}

}  // namespace ddhgs::core
