// Raw colour tables behind core/colour.h: 380-780 nm at 5 nm steps.
#pragma once

namespace ddhgs::core {

constexpr int kColourTableRows = 81;
constexpr double kColourTableStartNm = 380.0;
constexpr double kColourTableStepNm = 5.0;

extern const double kCie1931Cmf[kColourTableRows][3];  // xbar, ybar, zbar
extern const double kD65Power[kColourTableRows];       // relative, 100 at 560 nm

}  // namespace ddhgs::core
