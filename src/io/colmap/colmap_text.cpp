// COLMAP's text model format: '#' comment lines, whitespace-separated fields;
// images.txt holds two lines per image, the second (keypoints) maybe empty.
#include <cstdio>
#include <sstream>

#include "core/error.h"
#include "io/colmap/colmap.h"
#include "io/files/atomic_file.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

struct Line {
  size_t number;  // 1-based, for messages
  std::string text;
};

std::vector<Line> read_lines(const fs::path& path) {
  std::istringstream in(read_file(path));
  std::vector<Line> lines;
  std::string text;
  for (size_t number = 1; std::getline(in, text); ++number) {
    if (!text.empty() && text.back() == '\r') text.pop_back();
    if (!text.empty() && text[0] == '#') continue;
    lines.push_back({number, text});
  }
  return lines;
}

bool blank(const std::string& text) {
  return text.find_first_not_of(" \t") == std::string::npos;
}

// Parses one line field by field; any missing or malformed field is an error
// naming the file and line.
class Fields {
 public:
  Fields(const fs::path& path, const Line& line) : path_(path), line_(line), in_(line.text) {}

  template <typename T>
  T next(const char* what) {
    T value;
    if (!(in_ >> value)) fail(std::string("expected ") + what);
    return value;
  }
  bool done() {
    in_ >> std::ws;
    return in_.eof();
  }
  std::string rest() {
    std::string out;
    std::getline(in_ >> std::ws, out);
    while (!out.empty() && (out.back() == ' ' || out.back() == '\t')) out.pop_back();
    return out;
  }
  [[noreturn]] void fail(const std::string& problem) const {
    throw core::Error(path_, "line " + std::to_string(line_.number) + ": " + problem);
  }

 private:
  const fs::path& path_;
  const Line& line_;
  std::istringstream in_;
};

void read_cameras_text(const fs::path& path, ColmapModel& model) {
  for (const Line& line : read_lines(path)) {
    if (blank(line.text)) continue;
    Fields f(path, line);
    ColmapCamera camera;
    camera.camera_id = f.next<int>("camera id");
    camera.model = f.next<std::string>("camera model");
    camera.width = f.next<int64_t>("width");
    camera.height = f.next<int64_t>("height");
    for (int64_t pixels : {camera.width, camera.height})
      if (pixels < 1 || pixels > kColmapMaxPixels)
        f.fail("image size " + std::to_string(pixels) + " is not between 1 and " +
               std::to_string(kColmapMaxPixels) + " pixels");
    size_t count =
        colmap_param_count(camera.model, path.string() + ": line " + std::to_string(line.number));
    for (size_t j = 0; j < count; ++j) camera.params.push_back(f.next<double>("camera parameter"));
    if (!f.done()) f.fail("more parameters than model " + camera.model + " takes");
    if (!model.cameras.emplace(camera.camera_id, camera).second)
      f.fail("camera id " + std::to_string(camera.camera_id) + " appears twice");
  }
}

void read_images_text(const fs::path& path, ColmapModel& model) {
  std::vector<Line> lines = read_lines(path);
  size_t i = 0;
  while (i < lines.size()) {
    if (blank(lines[i].text)) {
      ++i;
      continue;
    }
    Fields f(path, lines[i]);
    ColmapImage image;
    image.image_id = f.next<int>("image id");
    for (double& q : image.qvec) q = f.next<double>("quaternion");
    image.tvec.x = f.next<double>("translation");
    image.tvec.y = f.next<double>("translation");
    image.tvec.z = f.next<double>("translation");
    image.camera_id = f.next<int>("camera id");
    // Names may contain spaces: the name is the rest of the line.
    image.name = f.rest();
    if (image.name.empty()) f.fail("expected an image name");
    ++i;
    if (i < lines.size()) {
      Fields points(path, lines[i]);
      while (!points.done()) {
        double x = points.next<double>("keypoint x");
        double y = points.next<double>("keypoint y");
        image.xys.push_back({x, y});
        image.point3d_ids.push_back(points.next<int64_t>("keypoint point3D id"));
      }
      ++i;
    }
    model.images.push_back(std::move(image));
  }
}

void read_points_text(const fs::path& path, ColmapModel& model) {
  for (const Line& line : read_lines(path)) {
    if (blank(line.text)) continue;
    Fields f(path, line);
    ColmapPoint point;
    point.point3d_id = f.next<int64_t>("point id");
    point.xyz.x = f.next<double>("x");
    point.xyz.y = f.next<double>("y");
    point.xyz.z = f.next<double>("z");
    for (uint8_t& c : point.rgb) {
      int value = f.next<int>("colour");
      if (value < 0 || value > 255) f.fail("colour outside 0..255");
      c = uint8_t(value);
    }
    point.error = f.next<double>("error");
    while (!f.done()) {
      int image_id = f.next<int>("track image id");
      point.track.emplace_back(image_id, f.next<int>("track keypoint index"));
    }
    model.points.push_back(std::move(point));
  }
}

// 17 significant digits read back to the same double.
std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

}  // namespace

ColmapModel read_colmap_text(const fs::path& dir) {
  ColmapModel model;
  read_cameras_text(dir / "cameras.txt", model);
  read_images_text(dir / "images.txt", model);
  if (fs::exists(dir / "points3D.txt")) read_points_text(dir / "points3D.txt", model);
  model.cameras_file = dir / "cameras.txt";
  model.images_file = dir / "images.txt";
  return model;
}

void write_colmap_text(const fs::path& dir, const ColmapModel& model) {
  check_colmap_model(model);
  fs::create_directories(dir);
  std::ostringstream cameras;
  cameras << "# Camera list with one line of data per camera:\n"
          << "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
          << "# Number of cameras: " << model.cameras.size() << "\n";
  for (const auto& [id, camera] : model.cameras) {
    cameras << id << " " << camera.model << " " << camera.width << " " << camera.height;
    for (double p : camera.params) cameras << " " << num(p);
    cameras << "\n";
  }

  std::ostringstream images;
  images << "# Image list with two lines of data per image:\n"
         << "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
         << "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
         << "# Number of images: " << model.images.size() << "\n";
  for (const auto& image : model.images) {
    images << image.image_id;
    for (double q : image.qvec) images << " " << num(q);
    images << " " << num(image.tvec.x) << " " << num(image.tvec.y) << " " << num(image.tvec.z)
           << " " << image.camera_id << " " << image.name << "\n";
    for (size_t j = 0; j < image.xys.size(); ++j)
      images << (j ? " " : "") << num(image.xys[j][0]) << " " << num(image.xys[j][1]) << " "
             << image.point3d_ids[j];
    images << "\n";
  }

  std::ostringstream points;
  points << "# 3D point list with one line of data per point:\n"
         << "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
         << "# Number of points: " << model.points.size() << "\n";
  for (const auto& point : model.points) {
    points << point.point3d_id << " " << num(point.xyz.x) << " " << num(point.xyz.y) << " "
           << num(point.xyz.z) << " " << int(point.rgb[0]) << " " << int(point.rgb[1]) << " "
           << int(point.rgb[2]) << " " << num(point.error);
    for (const auto& [image_id, index] : point.track) points << " " << image_id << " " << index;
    points << "\n";
  }

  write_file_atomically(dir / "cameras.txt", cameras.str());
  write_file_atomically(dir / "images.txt", images.str());
  write_file_atomically(dir / "points3D.txt", points.str());
}

}  // namespace ddhgs::io
