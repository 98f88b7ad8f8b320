// A tensor's values as a plain vector, for JSON and text output.
#pragma once
#include "core/tensor.h"

#include <vector>

namespace ddhgs::core {

// Every element of t, in row-major order, as double.
std::vector<double> to_doubles(const torch::Tensor& t);

}  // namespace ddhgs::core
