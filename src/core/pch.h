// Precompiled header shared by every target: LibTorch dominates compile time.
// Only the tensor API (core/tensor.h): the whole of torch/torch.h made every
// file pay about 5 s more to load it, though few use its modules,
// optimisers or serialisation.
#pragma once
#include "core/tensor.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>
