// LibTorch's tensor API: tensors, their operators, autograd (custom
// functions, grad modes) and the helpers of torch/utils.h. It leaves out
// torch/torch.h's modules (torch::nn), optimisers, data loaders, JIT and
// serialisation, which a file that uses them includes itself
// (<torch/nn/...>, <torch/optim/...>, <torch/serialize.h>). Parsing
// torch/torch.h costs about 27 s of CPU per file and loading it from the
// precompiled header about 7.5 s; this subset about 13 s and 2.7 s
// (docs/benchmarks.md, "Build time").
#pragma once
#include <torch/autograd.h>
#include <torch/types.h>
#include <torch/utils.h>
