// PLY files: round trips, hand-written ASCII files, files written and read
// independently by Python/numpy, and malformed files.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>

#include "core/error.h"
#include "io/ply/ply.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Runs a Python script (numpy available); fails the test on a non-zero exit.
void run_python(const fs::path& dir, const std::string& script) {
  write_text(dir / "script.py", script);
  std::string output;
  int rc = test::run_command(test::python() + " " + (dir / "script.py").string(), &output);
  ASSERT_EQ(rc, 0) << output;
}

// Expects core::Error whose message names the file.
template <typename F>
void expect_error_naming(const fs::path& path, F&& f, const std::string& fragment) {
  try {
    f();
    ADD_FAILURE() << "no error for " << path << " (" << fragment << ")";
  } catch (const core::Error& e) {
    std::string what = e.what();
    EXPECT_NE(what.find(path.string()), std::string::npos) << what;
    EXPECT_NE(what.find(fragment), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
}

GaussianPly random_gaussians(int64_t G, int64_t N, int64_t K) {
  torch::manual_seed(G * 100 + N * 10 + K);
  GaussianPly ply;
  ply.means = torch::randn({G, 3});
  ply.log_scales = torch::randn({G, 3}) - 3;
  ply.quats = torch::randn({G, 4});
  ply.logit_opacities = torch::randn({G, 1});
  ply.sh_dc = torch::randn({G, N});
  ply.sh_rest = torch::randn({G, N, K});
  for (int64_t b = 0; b < N; ++b) ply.wavelengths_nm.push_back(400.5 + 10.1 * double(b));
  return ply;
}

TEST(GaussianPly, RoundTripsEveryDegree) {
  auto dir = test::temp_dir("ply_round_trip");
  for (int64_t K : {0, 3, 8, 15})
    for (int64_t N : {1, 3, 7}) {
      auto ply = random_gaussians(11, N, K);
      write_gaussian_ply(dir / "g.ply", ply);
      auto back = read_gaussian_ply(dir / "g.ply");
      EXPECT_EQ(back.sh_degree(), K == 0 ? 0 : K == 3 ? 1 : K == 8 ? 2 : 3);
      EXPECT_EQ(back.bands(), N);
      EXPECT_TRUE(torch::equal(back.means, ply.means));
      EXPECT_TRUE(torch::equal(back.log_scales, ply.log_scales));
      EXPECT_TRUE(torch::equal(back.quats, ply.quats));
      EXPECT_TRUE(torch::equal(back.logit_opacities, ply.logit_opacities));
      EXPECT_TRUE(torch::equal(back.sh_dc, ply.sh_dc));
      EXPECT_TRUE(torch::equal(back.sh_rest, ply.sh_rest));
      EXPECT_EQ(back.wavelengths_nm, ply.wavelengths_nm);  // exact: shortest round-trip text
    }
  auto empty = random_gaussians(0, 2, 3);
  write_gaussian_ply(dir / "empty.ply", empty);
  EXPECT_EQ(read_gaussian_ply(dir / "empty.ply").means.size(0), 0);
}

TEST(GaussianPly, HeaderHasTheDocumentedLayout) {
  auto dir = test::temp_dir("ply_header");
  auto ply = random_gaussians(2, 2, 3);
  ply.wavelengths_nm = {450, 550.25};
  write_gaussian_ply(dir / "g.ply", ply);
  std::string text = read_text(dir / "g.ply");
  std::string header = text.substr(0, text.find("end_header\n") + 11);
  std::string expected =
      "ply\nformat binary_little_endian 1.0\ncomment wavelengths 450 550.25\n"
      "element vertex 2\n";
  for (std::string name : {"x",        "y",        "z",        "nx",       "ny",       "nz",
                           "f_dc_0",   "f_dc_1",   "f_rest_0", "f_rest_1", "f_rest_2", "f_rest_3",
                           "f_rest_4", "f_rest_5", "opacity",  "scale_0",  "scale_1",  "scale_2",
                           "rot_0",    "rot_1",    "rot_2",    "rot_3"})
    expected += "property float " + name + "\n";
  EXPECT_EQ(header, expected + "end_header\n");
  EXPECT_EQ(text.size(), header.size() + 2 * 22 * 4);
}

// Python reads our file with its own parser and checks band-major f_rest.
TEST(GaussianPly, ReadableByNumpyWithBandMajorRest) {
  auto dir = test::temp_dir("ply_numpy_reads");
  const int64_t G = 3, N = 4, K = 8;
  GaussianPly ply = random_gaussians(G, N, K);
  // sh_rest[g, b, k] = 100 g + 10 b + k
  ply.sh_rest = (torch::arange(G).view({G, 1, 1}) * 100 + torch::arange(N).view({1, N, 1}) * 10 +
                 torch::arange(K).view({1, 1, K}))
                    .to(torch::kFloat32);
  ply.sh_dc = torch::arange(G * N).view({G, N}).to(torch::kFloat32);
  write_gaussian_ply(dir / "g.ply", ply);
  run_python(dir, R"(
import numpy as np, sys
data = open(sys.argv[0].replace('script.py', 'g.ply'), 'rb').read()
end = data.index(b'end_header\n') + len('end_header\n')
names = [l.split()[2] for l in data[:end].decode().splitlines() if l.startswith('property')]
rows = np.frombuffer(data[end:], dtype='<f4').reshape(3, len(names))
col = {n: i for i, n in enumerate(names)}
for g in range(3):
    for b in range(4):
        assert rows[g, col['f_dc_%d' % b]] == g * 4 + b
        for k in range(8):
            assert rows[g, col['f_rest_%d' % (b * 8 + k)]] == 100 * g + 10 * b + k
assert (rows[:, col['nx']] == 0).all()
)");
}

// numpy writes a file in a different property order, with extra properties
// and a double-typed x; the reader must map by name.
TEST(GaussianPly, ReadsNumpyFileWithShuffledAndExtraProperties) {
  auto dir = test::temp_dir("ply_numpy_writes");
  run_python(dir, R"(
import numpy as np, sys
N, K = 2, 3
names = ['rot_3', 'f_rest_5', 'opacity', 'x', 'extra', 'f_dc_1', 'y', 'z'] + \
        ['f_rest_%d' % i for i in range(5)] + ['f_dc_0', 'scale_0', 'scale_1', 'scale_2', 'rot_0', 'rot_1', 'rot_2']
types = [('x', '<f8') if n == 'x' else (n, '<f4') for n in names]
rows = np.zeros(2, dtype=types)
for g in range(2):
    for i, n in enumerate(names):
        rows[n][g] = (1000 * g + i) / 100.0
header = 'ply\nformat binary_little_endian 1.0\ncomment made by numpy\ncomment wavelengths 500 600\n'
header += 'element vertex 2\n' + ''.join('property %s %s\n' % ('double' if n == 'x' else 'float', n) for n in names)
header += 'end_header\n'
open(sys.argv[0].replace('script.py', 'g.ply'), 'wb').write(header.encode() + rows.tobytes())
)");
  auto ply = read_gaussian_ply(dir / "g.ply");
  ASSERT_EQ(ply.bands(), 2);
  ASSERT_EQ(ply.sh_degree(), 1);
  EXPECT_EQ(ply.wavelengths_nm, (std::vector<double>{500, 600}));
  // Property i of Gaussian g holds (1000 g + i) / 100 (positions in `names`
  // above; scale_* stay below the largest accepted, 20).
  auto at = [](int g, int i) { return float((1000 * g + i) / 100.0); };
  for (int g = 0; g < 2; ++g) {
    EXPECT_EQ(ply.means[g][0].item<float>(), at(g, 3));
    EXPECT_EQ(ply.means[g][1].item<float>(), at(g, 6));
    EXPECT_EQ(ply.means[g][2].item<float>(), at(g, 7));
    EXPECT_EQ(ply.quats[g][3].item<float>(), at(g, 0));
    EXPECT_EQ(ply.quats[g][0].item<float>(), at(g, 17));
    EXPECT_EQ(ply.logit_opacities[g][0].item<float>(), at(g, 2));
    EXPECT_EQ(ply.sh_dc[g][0].item<float>(), at(g, 13));
    EXPECT_EQ(ply.sh_dc[g][1].item<float>(), at(g, 5));
    EXPECT_EQ(ply.log_scales[g][2].item<float>(), at(g, 16));
    EXPECT_EQ(ply.sh_rest[g][1][2].item<float>(), at(g, 1));   // f_rest_5 = band 1, k 2
    EXPECT_EQ(ply.sh_rest[g][1][0].item<float>(), at(g, 11));  // f_rest_3
    EXPECT_EQ(ply.sh_rest[g][0][0].item<float>(), at(g, 8));   // f_rest_0
  }
}

TEST(GaussianPly, ReadsHandWrittenAsciiFile) {
  auto dir = test::temp_dir("ply_ascii_gaussian");
  write_text(dir / "g.ply",
             "ply\r\nformat ascii 1.0\r\ncomment wavelengths 700\r\nelement vertex 2\r\n"
             "property float opacity\r\nproperty float f_dc_0\r\nproperty float x\r\n"
             "property float y\r\nproperty float z\r\nproperty float scale_0\r\n"
             "property float scale_1\r\nproperty float scale_2\r\nproperty float rot_0\r\n"
             "property float rot_1\r\nproperty float rot_2\r\nproperty float rot_3\r\n"
             "property uchar label\r\nend_header\r\n"
             "0.5 1.25 1 2 3 -4 -5 -6 1 0 0 0 7\r\n"
             "\r\n"
             "-2 -0.75 4e1 5 6 -1 -1 -1 0.5 0.5 0.5 0.5 8\r\n");
  auto ply = read_gaussian_ply(dir / "g.ply");
  EXPECT_EQ(ply.sh_degree(), 0);
  EXPECT_EQ(ply.wavelengths_nm, std::vector<double>{700});
  EXPECT_TRUE(torch::equal(ply.means, torch::tensor({{1.f, 2.f, 3.f}, {40.f, 5.f, 6.f}})));
  EXPECT_TRUE(torch::equal(ply.sh_dc, torch::tensor({{1.25f}, {-0.75f}})));
  EXPECT_TRUE(torch::equal(ply.logit_opacities, torch::tensor({{0.5f}, {-2.f}})));
  EXPECT_TRUE(
      torch::equal(ply.log_scales, torch::tensor({{-4.f, -5.f, -6.f}, {-1.f, -1.f, -1.f}})));
  EXPECT_TRUE(torch::equal(ply.quats, torch::tensor({{1.f, 0.f, 0.f, 0.f}, {.5f, .5f, .5f, .5f}})));
}

TEST(PointPly, RoundTripsWithColoursAndSpectra) {
  auto dir = test::temp_dir("ply_points");
  PointCloud points;
  points.xyz = torch::randn({20, 3});
  points.rgb = torch::randint(0, 256, {20, 3}).to(torch::kUInt8);
  points.spectra = torch::rand({20, 5});
  write_point_ply(dir / "p.ply", points);
  auto back = read_point_ply(dir / "p.ply");
  EXPECT_TRUE(torch::equal(back.xyz, points.xyz));
  EXPECT_TRUE(torch::equal(back.rgb, points.rgb));
  EXPECT_TRUE(torch::equal(back.spectra, points.spectra));

  PointCloud bare;
  bare.xyz = points.xyz;
  write_point_ply(dir / "bare.ply", bare);
  auto bare_back = read_point_ply(dir / "bare.ply");
  EXPECT_TRUE(torch::equal(bare_back.xyz, bare.xyz));
  EXPECT_FALSE(bare_back.rgb.defined());
  EXPECT_FALSE(bare_back.spectra.defined());
}

TEST(PointPly, ReadsAsciiWithFacesAfterVertices) {
  auto dir = test::temp_dir("ply_points_ascii");
  write_text(dir / "p.ply",
             "ply\nformat ascii 1.0\nobj_info from a mesh tool\nelement vertex 3\n"
             "property float x\nproperty float y\nproperty float z\n"
             "property uchar red\nproperty uchar green\nproperty uchar blue\n"
             "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
             "0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0.5 0 0 255\n3 0 1 2\n");
  auto points = read_point_ply(dir / "p.ply");
  EXPECT_TRUE(
      torch::equal(points.xyz, torch::tensor({{0.f, 0.f, 0.f}, {1.f, 0.f, 0.f}, {0.f, 1.f, .5f}})));
  EXPECT_TRUE(torch::equal(points.rgb,
                           torch::tensor({{255, 0, 0}, {0, 255, 0}, {0, 0, 255}}, torch::kUInt8)));
  EXPECT_FALSE(points.spectra.defined());
}

// COLMAP / 3DGS style exports: double xyz with normals and uchar colours,
// little and big endian, and a list element before the vertices.
TEST(PointPly, ReadsNumpyExportsWithDoubleXyz) {
  auto dir = test::temp_dir("ply_points_numpy");
  run_python(dir, R"(
import numpy as np, sys
out = sys.argv[0].replace('script.py', '')
for endian, name in (('<', 'little'), ('>', 'big')):
    v = np.zeros(4, dtype=[('x', endian + 'f8'), ('y', endian + 'f8'), ('z', endian + 'f8'),
                           ('nx', endian + 'f4'), ('ny', endian + 'f4'), ('nz', endian + 'f4'),
                           ('red', 'u1'), ('green', 'u1'), ('blue', 'u1')])
    for i in range(4):
        v[i] = (i + 0.1, -i, 2.5 * i, 0, 0, 1, 10 * i, 20 * i, 30 * i)
    cam = np.array([3], dtype='u1').tobytes() + np.array([7, 8, 9], dtype=endian + 'i4').tobytes()
    header = ('ply\nformat binary_%s_endian 1.0\nelement camera 1\nproperty list uchar int ids\n'
              'element vertex 4\nproperty double x\nproperty double y\nproperty double z\n'
              'property float nx\nproperty float ny\nproperty float nz\n'
              'property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n') % name
    open(out + name + '.ply', 'wb').write(header.encode() + cam + v.tobytes())
)");
  for (const char* name : {"little.ply", "big.ply"}) {
    auto points = read_point_ply(dir / name);
    ASSERT_EQ(points.xyz.size(0), 4) << name;
    for (int i = 0; i < 4; ++i) {
      EXPECT_EQ(points.xyz[i][0].item<float>(), float(i + 0.1)) << name;
      EXPECT_EQ(points.xyz[i][1].item<float>(), float(-i)) << name;
      EXPECT_EQ(points.xyz[i][2].item<float>(), float(2.5 * i)) << name;
      EXPECT_EQ(int(points.rgb[i][2].item<uint8_t>()), 30 * i) << name;
    }
  }
}

TEST(Ply, MalformedFilesGiveOneLineErrorsNamingTheFile) {
  auto dir = test::temp_dir("ply_malformed");
  auto good = random_gaussians(5, 2, 3);
  write_gaussian_ply(dir / "good.ply", good);
  const std::string bytes = read_text(dir / "good.ply");
  const size_t header_end = bytes.find("end_header\n") + 11;
  auto gaussian_case = [&](const std::string& name, const std::string& content,
                           const std::string& fragment) {
    write_text(dir / name, content);
    expect_error_naming(
        dir / name, [&] { read_gaussian_ply(dir / name); }, fragment);
  };
  auto replaced = [&](std::string from, std::string to) {
    std::string s = bytes;
    s.replace(s.find(from), from.size(), to);
    return s;
  };
  gaussian_case("truncated.ply", bytes.substr(0, bytes.size() - 10), "truncated");
  gaussian_case("header_only.ply", bytes.substr(0, header_end - 11), "end_header");
  gaussian_case("magic.ply", "plx" + bytes.substr(3), "not a PLY file");
  // Header edits of the good file: {file, text replaced, replacement, expected message}.
  const std::vector<std::array<std::string, 4>> edits = {
      {"count.ply", "element vertex 5", "element vertex 500000000000", "truncated"},
      {"no_opacity.ply", "property float opacity", "property float opaque", "'opacity'"},
      {"rest.ply", "property float f_rest_5\n", "property float unused\n",
       "5 f_rest_* properties for 2 bands"},
      {"dc_gap.ply", "property float f_dc_1\n", "property float f_dc_7\n", "f_dc_1 is missing"},
      {"wavelengths.ply", "comment wavelengths 400.5", "comment wavelengths", "lists 1 values"},
      {"format.ply", "binary_little_endian", "binary_middle_endian", "unknown format"},
      {"type.ply", "property float x", "property float16 x", "unknown type"},
  };
  for (const auto& [name, from, to, fragment] : edits)
    gaussian_case(name, replaced(from, to), fragment);
  std::string nan = bytes;
  const float not_a_number = std::nanf("");
  std::memcpy(&nan[header_end + 4], &not_a_number, 4);  // y of Gaussian 0
  gaussian_case("nan.ply", nan, "'y' of vertex 0 is not a finite number");
  // A minimal ASCII Gaussian file (12 properties) with `count` vertices.
  auto ascii_file = [](int count, const std::string& body) {
    std::string header = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(count) + "\n";
    for (const char* name : {"x", "y", "z", "f_dc_0", "opacity", "scale_0", "scale_1", "scale_2",
                             "rot_0", "rot_1", "rot_2", "rot_3"})
      header += std::string("property float ") + name + "\n";
    return header + "end_header\n" + body;
  };
  gaussian_case("ascii.ply", ascii_file(1, "1 2 3 4 5 6 7 8 9 1O 11 12\n"), "not a number");
  gaussian_case("ascii_short.ply", ascii_file(2, "1 2 3 4 5 6 7 8 9 10 11 12\n1 2 3\n"),
                "truncated");
  gaussian_case("ascii_count.ply", ascii_file(1, "1 2 3 4 5 6 7 8 9 10 11.25\n"),
                "has 11 values, expected 12");
  expect_error_naming(
      dir / "missing.ply", [&] { read_gaussian_ply(dir / "missing.ply"); }, "not found");
  write_text(dir / "no_xyz.ply",
             "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n");
  expect_error_naming(
      dir / "no_xyz.ply", [&] { read_point_ply(dir / "no_xyz.ply"); }, "'y'");
  write_text(dir / "faces.ply", "ply\nformat ascii 1.0\nelement face 0\nend_header\n");
  expect_error_naming(
      dir / "faces.ply", [&] { read_point_ply(dir / "faces.ply"); }, "'vertex'");
}

TEST(Ply, NumbersFloat32CannotRenderAreRefusedNamingWhere) {
  auto dir = test::temp_dir("ply_range");
  GaussianPly latent = random_gaussians(4, 2, 3);  // 2 latent channels
  latent.wavelengths_nm = {450, 550, 650};
  latent.basis = torch::randn({3, 2});
  latent.mean = torch::rand({3});
  write_gaussian_ply(dir / "latent.ply", latent);
  const std::string bytes = read_text(dir / "latent.ply");
  const size_t basis_line =
      bytes.find("comment band_basis ", bytes.find("comment band_basis ") + 1);
  const size_t header_end = bytes.find("end_header\n") + 11;
  // The second basis line's mean replaced by `value`.
  auto basis_value = [&](const std::string& value) {
    std::string s = bytes;
    const size_t first = basis_line + std::string("comment band_basis ").size();
    s.replace(first, s.find(' ', first) - first, value);
    return s;
  };
  auto refused = [&](const std::string& name, const std::string& content,
                     const std::string& fragment) {
    write_text(dir / name, content);
    expect_error_naming(
        dir / name, [&] { read_gaussian_ply(dir / name); }, fragment);
  };
  refused("basis_1e39.ply", basis_value("1e39"),
          "'comment band_basis' line 2: '1e39' is out of range (at most 1e+18 in magnitude)");
  refused("basis_1e400.ply", basis_value("-1e400"), "line 2: '-1e400' is out of range");
  refused("basis_inf.ply", basis_value("inf"), "line 2: 'inf' is out of range");
  refused("basis_nan.ply", basis_value("nan"), "line 2 has a non-number 'nan'");
  refused("basis_long.ply", basis_value(std::string(1000, '7')),
          "line 2: '" + std::string(80, '7') + "...' (and 920 more characters) is out of range");
  std::string wavelengths = bytes;
  wavelengths.replace(wavelengths.find("comment wavelengths 450"), 23, "comment wavelengths 4e20");
  refused("wavelength_4e20.ply", wavelengths, "'comment wavelengths': '4e20' is out of range");
  // A value just inside reads.
  write_text(dir / "edge.ply", basis_value("1e18"));
  EXPECT_EQ(read_gaussian_ply(dir / "edge.ply").mean[1].item<float>(), 1e18f);

  // Vertex values: finite float32, but what no render survives.
  auto vertex_value = [&](const std::string& property, float value) {
    // Properties of the binary body in header order; Gaussian 0's value.
    std::vector<std::string> order;
    for (size_t at = bytes.find("property float "); at < header_end;
         at = bytes.find("property float ", at + 1)) {
      const size_t start = at + 15;
      order.push_back(bytes.substr(start, bytes.find('\n', start) - start));
    }
    const size_t index = size_t(std::find(order.begin(), order.end(), property) - order.begin());
    EXPECT_LT(index, order.size()) << property;
    std::string s = bytes;
    std::memcpy(&s[header_end + 4 * index], &value, 4);
    return s;
  };
  refused("f_dc_1e30.ply", vertex_value("f_dc_1", 1e30f),
          "f_dc_* of Gaussian 0 is 1e+30 (at most 1e+18 in magnitude)");
  refused("rot_3e38.ply", vertex_value("rot_2", -3e38f), "rot_* of Gaussian 0 is 3e+38");
  refused("scale_25.ply", vertex_value("scale_1", 25.f),
          "scale_* of Gaussian 0 is 25, a width of 7.20049e+10 units");
  write_text(dir / "scale_19.ply", vertex_value("scale_1", 19.f));
  EXPECT_EQ(read_gaussian_ply(dir / "scale_19.ply").log_scales[0][1].item<float>(), 19.f);
}

TEST(Ply, OnlyRegularFilesAreRead) {
  auto dir = test::temp_dir("ply_special");
  ASSERT_EQ(::mkfifo((dir / "pipe.ply").c_str(), 0600), 0);
  expect_error_naming(
      dir / "pipe.ply", [&] { read_gaussian_ply(dir / "pipe.ply"); }, "is a FIFO (named pipe)");
  expect_error_naming(
      dir / "pipe.ply", [&] { read_point_ply(dir / "pipe.ply"); }, "is a FIFO (named pipe)");
  fs::create_directories(dir / "folder.ply");
  expect_error_naming(
      dir / "folder.ply", [&] { read_gaussian_ply(dir / "folder.ply"); }, "is a folder");
}

TEST(Ply, WriterRejectsBadShapesAndLeavesNoFile) {
  auto dir = test::temp_dir("ply_bad_write");
  auto ply = random_gaussians(4, 3, 3);
  auto bad = ply;
  bad.sh_rest = torch::zeros({4, 3, 5});
  expect_error_naming(
      dir / "a.ply", [&] { write_gaussian_ply(dir / "a.ply", bad); }, "sh_rest");
  bad = ply;
  bad.quats = torch::zeros({3, 4});
  expect_error_naming(
      dir / "a.ply", [&] { write_gaussian_ply(dir / "a.ply", bad); }, "quats");
  bad = ply;
  bad.wavelengths_nm = {500};
  expect_error_naming(
      dir / "a.ply", [&] { write_gaussian_ply(dir / "a.ply", bad); }, "1 wavelengths for 3 bands");
  PointCloud points;
  points.xyz = torch::zeros({4, 3});
  points.rgb = torch::zeros({4, 3});  // float, not uint8
  expect_error_naming(
      dir / "p.ply", [&] { write_point_ply(dir / "p.ply", points); }, "rgb");
  EXPECT_TRUE(fs::is_empty(dir));
}

}  // namespace
}  // namespace ddhgs::io
