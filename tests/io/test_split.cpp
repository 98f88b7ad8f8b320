// The Hyper-NeRF train/test rule: train = floor(linspace(0, n-1, ceil(0.9 n))).
#include <gtest/gtest.h>

#include <algorithm>
#include <sstream>

#include "io/scene/scene.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {

std::vector<int> complement(int n, const std::vector<int>& holes) {
  std::vector<int> out;
  for (int i = 0; i < n; ++i)
    if (std::find(holes.begin(), holes.end(), i) == holes.end()) out.push_back(i);
  return out;
}

void expect_split(int n, const std::vector<int>& expected_test) {
  std::vector<int> train, test;
  hypernerf_split(n, train, test);
  EXPECT_EQ(test, expected_test) << "n = " << n;
  EXPECT_EQ(train, complement(n, expected_test)) << "n = " << n;
}

TEST(Split, HandComputedSmallScenes) {
  expect_split(1, {});  // ceil(0.9) = 1 view: train only
  expect_split(2, {});  // linspace(0, 1, 2) = {0, 1}
  expect_split(3, {});  // ceil(2.7) = 3
  // n = 10: 9 train views, step 9/8: 0 1.125 2.25 3.375 4.5 5.625 6.75 7.875 9.
  expect_split(10, {8});
  // n = 11: 10 train views, step 10/9: ... 7.78 8.89 10.
  expect_split(11, {9});
}

TEST(Split, SurfaceOpticsAndBaySpecSizes) {
  // 48 views (Surface Optics): 44 train, step 47/43.
  expect_split(48, {11, 23, 35, 46});
  // 433 views (BaySpec): 390 train, 43 test, mostly every tenth view.
  std::vector<int> test;
  for (int i = 10; i <= 210; i += 10) test.push_back(i);
  for (int i = 221; i <= 431; i += 10) test.push_back(i);
  expect_split(433, test);
}

TEST(Split, EmptyScene) {
  std::vector<int> train = {7}, test = {8};
  hypernerf_split(0, train, test);
  EXPECT_TRUE(train.empty());
  EXPECT_TRUE(test.empty());
}

TEST(Split, MatchesNumpyForEverySizeUpTo500) {
  std::string out;
  std::string script =
      "import math, numpy as np\n"
      "for n in range(1, 501):\n"
      "    k = math.ceil(n * 0.9)\n"
      "    print(' '.join(str(i) for i in np.linspace(0, n - 1, k).astype(int)))\n";
  std::string command = test::python() + " -c \"" + script + "\"";
  if (test::run_command(command, &out) != 0) GTEST_SKIP() << "python3 with numpy unavailable";
  std::istringstream lines(out);
  std::string line;
  for (int n = 1; n <= 500; ++n) {
    ASSERT_TRUE(std::getline(lines, line)) << "numpy output ends at n = " << n;
    std::istringstream fields(line);
    std::vector<int> expected;
    for (int i; fields >> i;) expected.push_back(i);
    std::vector<int> train, test;
    hypernerf_split(n, train, test);
    ASSERT_EQ(train, expected) << "n = " << n;
    ASSERT_EQ(train.size() + test.size(), size_t(n));
  }
}

}  // namespace
}  // namespace ddhgs::io
