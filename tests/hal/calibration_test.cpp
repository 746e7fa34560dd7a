// camera_info YAML -> PinholeIntrinsics, and the one-line errors for every malformed field.
#include <catch2/catch.hpp>

#include <cstdio>
#include <fstream>
#include <string>

#include "hal/calibration/camera_info.hpp"

using vantage::PinholeIntrinsics;
using vantage::hal::load_camera_info;
using vantage::hal::parse_camera_info;

namespace {

// As written by ROS camera_calibration (camera_calibration_parsers' YAML layout).
std::string camera_info(const std::string& distortion = "[-0.28, 0.07, 0.0, 0.0, 0.0]",
                        const std::string& matrix = "[525.5, 0.0, 319.5, 0.0, 524.0, 239.5, 0.0, 0.0, 1.0]",
                        const std::string& model = "plumb_bob") {
  return "image_width: 640\n"
         "image_height: 480\n"
         "camera_name: narrow_stereo\n"
         "camera_matrix:\n  rows: 3\n  cols: 3\n  data: " + matrix + "\n"
         "distortion_model: " + model + "\n"
         "distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: " + distortion + "\n"
         "rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"
         "projection_matrix:\n  rows: 3\n  cols: 4\n  data: [525.5, 0, 319.5, 0, 0, 524.0, 239.5, 0, 0, 0, 1, 0]\n";
}

std::string error_for(const std::string& text) {
  PinholeIntrinsics k;
  k.fx_px = 42.0;
  std::string note;
  const std::string error = parse_camera_info(text, "cam.yaml", &k, &note);
  CHECK(k.fx_px == 42.0);  // untouched on error
  return error;
}

}  // namespace

TEST_CASE("a ROS camera_info file gives the intrinsics", "[calibration]") {
  PinholeIntrinsics k;
  std::string note = "stale";
  REQUIRE(parse_camera_info(camera_info(), "cam.yaml", &k, &note) == "");
  CHECK(k.width_px == 640);
  CHECK(k.height_px == 480);
  CHECK(k.fx_px == 525.5);
  CHECK(k.fy_px == 524.0);
  CHECK(k.cx_px == 319.5);
  CHECK(k.cy_px == 239.5);
  CHECK(k.k1 == -0.28);
  CHECK(k.k2 == 0.07);
  CHECK(note.empty());
}

TEST_CASE("small tangential and k3 terms are ignored with a note", "[calibration]") {
  PinholeIntrinsics k;
  std::string note;
  REQUIRE(parse_camera_info(camera_info("[-0.28, 0.07, 0.0001, -0.0001, 0.0]"), "cam.yaml", &k, &note) == "");
  CHECK(note.find("cam.yaml: p1, p2, k3 ignored") == 0);
}

TEST_CASE("large tangential or k3 terms are refused naming the field", "[calibration]") {
  const std::string error = error_for(camera_info("[-0.28, 0.07, 0.01, 0.0, 0.0]"));
  CHECK(error.find("cam.yaml: distortion_coefficients.data: p1, p2, k3 move the image corners") == 0);
  CHECK(error_for(camera_info("[-0.28, 0.07, 0.0, 0.0, 0.2]")).find("distortion_coefficients.data") != std::string::npos);
}

TEST_CASE("malformed camera_info fields give one line naming file and field", "[calibration]") {
  CHECK(error_for("image_height: 480\n") == "cam.yaml: image_width: missing or not a number");
  CHECK(error_for(camera_info("[-0.28, 0.07, 0.0, 0.0, 0.0]", "[525.5, 0.0, 319.5, 0.0, 524.0, 239.5, 0.0, 0.0]")) ==
        "cam.yaml: camera_matrix.data: expected 9 numbers, got 8");
  CHECK(error_for(camera_info("[-0.28, 0.07, 0.0, 0.0, 0.0]", "[525.5, 0.0, 319.5, x, 524.0, 239.5, 0.0, 0.0, 1.0]")) ==
        "cam.yaml: camera_matrix.data[3]: 'x' is not a number");
  CHECK(error_for(camera_info("[-0.28, 0.07, 0.0, 0.0]")) ==
        "cam.yaml: distortion_coefficients.data: expected 5 numbers, got 4");
  CHECK(error_for(camera_info("[-0.28, 0.07, 0.0, 0.0, 0.0]", "[525.5, 0.0, 319.5, 0.0, 524.0, 239.5, 0.0, 0.0, 1.0]",
                              "rational_polynomial")) ==
        "cam.yaml: distortion_model: 'rational_polynomial' is not supported (only plumb_bob)");
  CHECK(error_for(camera_info("[-0.28, 0.07, 0.0, 0.0, 0.0]", "[525.5, 1.0, 319.5, 0.0, 524.0, 239.5, 0.0, 0.0, 1.0]")) ==
        "cam.yaml: camera_matrix.data[1]: skew is not supported (must be 0)");
  CHECK(error_for(camera_info("[-0.28, 0.07, 0.0, 0.0, 0.0]", "[-525.5, 0.0, 319.5, 0.0, 524.0, 239.5, 0.0, 0.0, 1.0]"))
            .find("cam.yaml: camera_matrix: not a valid camera") == 0);
  CHECK(error_for("image_width: 640\nimage_height: [480\n").find("cam.yaml: line ") == 0);
  CHECK(error_for("- just\n- a list\n") == "cam.yaml: (document): not a camera_info mapping");
  CHECK(error_for("image_width: -3\n") == "cam.yaml: image_width: not a positive integer");
}

TEST_CASE("calibration files are read from disk and a missing file is named", "[calibration]") {
  const std::string path = "vantage_calibration_test_cam.yaml";
  {
    std::ofstream file(path);
    file << camera_info();
  }
  PinholeIntrinsics k;
  std::string note;
  CHECK(load_camera_info(path, &k, &note) == "");
  CHECK(k.fx_px == 525.5);
  std::remove(path.c_str());
  CHECK(load_camera_info("/nonexistent/cam.yaml", &k, &note) == "/nonexistent/cam.yaml: cannot open the calibration file");
}
