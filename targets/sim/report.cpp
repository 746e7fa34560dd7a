#include "targets/sim/report.hpp"

#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <vector>

#include "core/geometry/projection.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/planning/precision_level.hpp"

namespace vantage::simtarget {

namespace fs = std::filesystem;

namespace {

struct Rgb {
  std::uint8_t r, g, b;
};

// Blue (t = 0, low sigma) through cyan, green, yellow to red (t = 1, high sigma).
Rgb heat(double t) {
  t = std::clamp(t, 0.0, 1.0);
  const double r = std::clamp(1.5 - std::abs(4.0 * t - 3.0), 0.0, 1.0);
  const double g = std::clamp(1.5 - std::abs(4.0 * t - 2.0), 0.0, 1.0);
  const double b = std::clamp(1.5 - std::abs(4.0 * t - 1.0), 0.0, 1.0);
  return Rgb{static_cast<std::uint8_t>(255.0 * r), static_cast<std::uint8_t>(255.0 * g),
             static_cast<std::uint8_t>(255.0 * b)};
}

// Log scale from sigma_lo (blue) to sigma_hi (red).
struct SigmaScale {
  double lo = 1e-3;
  double hi = 1.0;
  double t(double sigma) const {
    if (!(sigma > 0.0)) return 0.0;
    return (std::log(sigma) - std::log(lo)) / (std::log(hi) - std::log(lo));
  }
};

SigmaScale sigma_scale(const PrimitivePoolView& pool, double sigma_target) {
  std::vector<double> sigmas;
  for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
    if (pool.is_alive(i)) sigmas.push_back(primitive_sigma(pool[i].Sigma_world));
  }
  SigmaScale s;
  s.lo = sigma_target / 4.0;
  s.hi = sigma_target * 25.0;
  if (!sigmas.empty()) {
    std::sort(sigmas.begin(), sigmas.end());
    s.hi = std::max(s.hi, sigmas[sigmas.size() * 98 / 100]);
  }
  return s;
}

bool write_png(const std::string& path, int width, int height, const std::vector<Rgb>& pixels, std::string* error) {
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) {
    *error = path + ": cannot open for writing";
    return false;
  }
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png != nullptr ? png_create_info_struct(png) : nullptr;
  if (png == nullptr || info == nullptr || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    std::fclose(file);
    *error = path + ": libpng failed to write the image";
    return false;
  }
  png_init_io(png, file);
  png_set_IHDR(png, info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height), 8, PNG_COLOR_TYPE_RGB,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  for (int y = 0; y < height; ++y) {
    png_write_row(png, reinterpret_cast<png_const_bytep>(pixels.data() + static_cast<std::size_t>(y) * width));
  }
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  const bool closed = std::fclose(file) == 0;
  if (!closed) *error = path + ": write failed";
  return closed;
}

// Splats the primitives into the view as discs with a depth buffer, coloured by sigma.
void splat(const PrimitivePoolView& pool, const Viewpoint& view, const PinholeIntrinsics& intrinsics,
           const SigmaScale& scale, int x0, int image_width, std::vector<Rgb>& pixels, std::vector<float>& depth) {
  for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
    if (!pool.is_alive(i)) continue;
    const Primitive& p = pool[i];
    const Eigen::Vector3d X_cam = view.R_world_cam.transpose() * (p.X_world - view.position_world);
    if (X_cam.z() <= 1e-6) continue;
    // Back-facing primitives are hidden (their footprint faces away from this camera).
    const Eigen::Vector3d to_camera = (view.position_world - p.X_world).normalized();
    if (p.normal_world.cast<double>().dot(to_camera) < -0.2) continue;
    const double u = intrinsics.fx_px * X_cam.x() / X_cam.z() + intrinsics.cx_px;
    const double v = intrinsics.fy_px * X_cam.y() / X_cam.z() + intrinsics.cy_px;
    const double r_px = std::clamp(1.2 * p.radius * intrinsics.fx_px / X_cam.z(), 1.0, 8.0);
    const Rgb colour = heat(scale.t(primitive_sigma(p.Sigma_world)));
    const int u_lo = static_cast<int>(std::floor(u - r_px)), u_hi = static_cast<int>(std::ceil(u + r_px));
    const int v_lo = static_cast<int>(std::floor(v - r_px)), v_hi = static_cast<int>(std::ceil(v + r_px));
    for (int y = std::max(0, v_lo); y <= std::min(intrinsics.height_px - 1, v_hi); ++y) {
      for (int x = std::max(0, u_lo); x <= std::min(intrinsics.width_px - 1, u_hi); ++x) {
        if ((x - u) * (x - u) + (y - v) * (y - v) > r_px * r_px) continue;
        const std::size_t k = static_cast<std::size_t>(y) * image_width + static_cast<std::size_t>(x0 + x);
        if (static_cast<float>(X_cam.z()) >= depth[k]) continue;
        depth[k] = static_cast<float>(X_cam.z());
        pixels[k] = colour;
      }
    }
  }
}

bool write_uncertainty_png(const std::string& path, const PrimitivePoolView& pool, const PinholeIntrinsics& intrinsics,
                           double viewing_distance, double sigma_target, std::string* error) {
  const int w = intrinsics.width_px, h = intrinsics.height_px;
  const int width = 2 * w;
  std::vector<Rgb> pixels(static_cast<std::size_t>(width) * h, Rgb{255, 255, 255});
  std::vector<float> depth(pixels.size(), std::numeric_limits<float>::infinity());
  const SigmaScale scale = sigma_scale(pool, sigma_target);
  // Two views from opposite sides (-y, the initial views' side, and +y), 20 degrees from above.
  for (int k = 0; k < 2; ++k) {
    const double azimuth = -0.5 * M_PI + k * M_PI;
    // 1.6 x the viewing distance so the whole object fits (at 1 x it fills half the image area).
    const double range = 1.6 * viewing_distance;
    const Eigen::Vector3d eye(range * std::cos(azimuth) * 0.94, range * std::sin(azimuth) * 0.94, range * 0.34);
    Viewpoint view;
    if (!ok(look_at(eye, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &view))) continue;
    splat(pool, view, intrinsics, scale, k * w, width, pixels, depth);
  }
  // A colour bar along the bottom edge: sigma from scale.lo (left) to scale.hi (right).
  for (int y = h - 12; y < h; ++y) {
    for (int x = 0; x < width; ++x) pixels[static_cast<std::size_t>(y) * width + x] = heat(double(x) / (width - 1));
  }
  return write_png(path, width, h, pixels, error);
}

bool write_text(const std::string& path, const std::string& text, std::string* error) {
  std::ofstream out(path);
  out << text;
  out.close();
  if (!out) {
    *error = path + ": write failed";
    return false;
  }
  return true;
}

std::string json_escape(const std::string& s) {
  std::string out;
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buffer[8];
      std::snprintf(buffer, sizeof buffer, "\\u%04x", c);
      out += buffer;
    } else {
      out += c;
    }
  }
  return out;
}

std::string grid_data(const GridGeometry& geo, const std::vector<float>& cost) {
  std::ostringstream out;
  out << "# x y cost (cell centres, scene units)\n";
  for (std::int32_t iy = 0; iy < geo.cells_per_side; ++iy) {
    for (std::int32_t ix = 0; ix < geo.cells_per_side; ++ix) {
      const Eigen::Vector2d xy = geo.cell_center_xy(GridCell{ix, iy});
      const float c = cost.empty() ? 1.0f : cost[static_cast<std::size_t>(geo.flat_index(GridCell{ix, iy}))];
      out << xy.x() << ' ' << xy.y() << ' ' << c << '\n';
    }
    out << '\n';
  }
  return out.str();
}

std::string cells_data(const GridGeometry& geo, const std::vector<GridCell>& cells, const char* header) {
  std::ostringstream out;
  out << "# " << header << "\n";
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const Eigen::Vector2d xy = geo.cell_center_xy(cells[i]);
    out << xy.x() << ' ' << xy.y() << ' ' << (i + 1) << '\n';
  }
  return out.str();
}

}  // namespace

bool prepare_output_dir(const std::string& dir, std::string* error) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) {
    *error = "--out " + dir + ": cannot create the report folder (" + (ec ? ec.message() : "not a directory") + ")";
    return false;
  }
  const std::string probe = (fs::path(dir) / ".vantage-write-probe").string();
  {
    std::ofstream out(probe);
    out << "probe\n";
    out.close();
    if (!out) {
      *error = "--out " + dir + ": the report folder is not writable";
      return false;
    }
  }
  fs::remove(probe, ec);
  return true;
}

// {"count": N, "median_scale": x, "median_in_top_bin": b, "beyond_95": y, "bins": [20 counts]}: the bins are
// chi-square(2)'s twentieths (NisHistogram), so an honest EKF fills them equally.
std::string innovations_json(const NisHistogram& innovations) {
  const NisSummary summary = summarize(innovations);
  std::ostringstream out;
  out << "{\"count\": " << summary.count << ", \"median_scale\": " << summary.median_scale
      << ", \"median_in_top_bin\": " << (summary.median_in_top_bin ? "true" : "false")
      << ", \"beyond_95\": " << summary.fraction_beyond_95 << ", \"bins\": [";
  for (std::size_t k = 0; k < innovations.counts.size(); ++k) out << (k > 0 ? ", " : "") << innovations.counts[k];
  out << "]}";
  return out.str();
}

std::string summary_json(const MissionSummary& s) {
  std::ostringstream out;
  out.precision(10);
  out << "{\n"
      << "  \"scene\": \"" << json_escape(s.scene) << "\",\n"
      << "  \"planner\": \"" << json_escape(s.planner) << "\",\n"
      << "  \"measurement\": \"" << json_escape(s.measurement) << "\",\n"
      << "  \"images\": " << s.images << ",\n"
      << "  \"nbv_iterations\": " << s.nbv_iterations << ",\n"
      << "  \"path_length\": " << s.path_length << ",\n"
      << "  \"coverage\": " << s.coverage << ",\n"
      << "  \"model_coverage\": " << s.model_coverage << ",\n"
      << "  \"verified_coverage\": " << s.verified_coverage << ",\n"
      << "  \"precise\": " << s.precise << ",\n"
      << "  \"precise_verified\": " << s.precise_verified << ",\n"
      << "  \"mean_sigma\": " << s.mean_sigma << ",\n"
      << "  \"accuracy_rms\": " << s.accuracy_rms << ",\n"
      << "  \"accuracy_p95\": " << s.accuracy_p95 << ",\n"
      << "  \"accuracy_rms_confirmed\": " << s.accuracy_rms_confirmed << ",\n"
      << "  \"accuracy_p95_confirmed\": " << s.accuracy_p95_confirmed << ",\n"
      << "  \"provisional\": " << s.provisional << ",\n"
      << "  \"accuracy_rms_provisional\": " << s.accuracy_rms_provisional << ",\n"
      << "  \"provisional_unobserved\": " << s.provisional_unobserved << ",\n"
      << "  \"accuracy_rms_unobserved\": " << s.accuracy_rms_unobserved << ",\n"
      << "  \"gross\": " << s.gross << ",\n"
      << "  \"gross_provisional\": " << s.gross_provisional << ",\n"
      << "  \"accuracy_rms_updated2\": " << s.accuracy_rms_updated2 << ",\n"
      << "  \"primitives\": " << s.primitives << ",\n"
      << "  \"reached_goal\": " << (s.reached_goal ? "true" : "false") << ",\n"
      << "  \"failed\": " << (s.failed ? "true" : "false") << ",\n"
      << "  \"end_reason\": \"" << json_escape(s.end_reason) << "\",\n"
      << "  \"planning_seconds\": " << s.planning_seconds << ",\n"
      << "  \"measurement_seconds\": " << s.measurement_seconds << ",\n"
      << "  \"render_seconds\": " << s.render_seconds << ",\n"
      << "  \"wall_seconds\": " << s.wall_seconds << ",\n"
      << "  \"grid_evaluations\": " << s.grid_evaluations << ",\n"
      << "  \"rejected_images\": " << s.rejected_images << ",\n"
      << "  \"unreachable_nbv\": " << s.unreachable_nbv << ",\n"
      << "  \"split_fallbacks\": " << s.split_fallbacks << ",\n"
      << "  \"stagnations\": " << s.stagnations << ",\n"
      << "  \"split_epsilon_cells\": " << s.split_epsilon_cells << ",\n"
      << "  \"coverage_target\": " << s.coverage_target << ",\n"
      << "  \"sigma_target\": " << s.sigma_target << ",\n"
      << "  \"budget\": " << s.budget << ",\n"
      << "  \"seed\": " << s.seed << ",\n"
      << "  \"tracks_predicted\": " << s.tracks_predicted << ",\n"
      << "  \"tracks_matched\": " << s.tracks_matched << ",\n"
      << "  \"tracks_inverse_warped\": " << s.tracks_inverse_warped << ",\n"
      << "  \"photometric_normals\": " << s.photometric_normals << ",\n"
      << "  \"photometric_refits_unconverged\": " << s.photometric_refits_unconverged << ",\n"
      << "  \"track_failures\": {\"template_masked\": " << s.track_failures.template_masked
      << ", \"below_threshold\": " << s.track_failures.below_threshold << ", \"ambiguous\": " << s.track_failures.ambiguous
      << ", \"no_subpixel\": " << s.track_failures.no_subpixel << ", \"no_room\": " << s.track_failures.no_room
      << ", \"edge_on\": " << s.track_failures.edge_on << ", \"too_uncertain\": " << s.track_failures.too_uncertain
      << "},\n"
      << "  \"seeds_tried\": " << s.seeds_tried << ",\n"
      << "  \"seeds_matched\": " << s.seeds_matched << ",\n"
      << "  \"seeds_beyond_depth_range\": " << s.seeds_beyond_depth_range << ",\n"
      << "  \"seeds_rejected_back_match\": " << s.seeds_rejected_back_match << ",\n"
      << "  \"seeds_rejected_no_plane_fit\": " << s.seeds_rejected_no_plane_fit << ",\n"
      << "  \"innovations\": " << innovations_json(s.innovations) << "\n"
      << "}\n";
  return out.str();
}

bool write_report(const std::string& dir, const MissionTrace& trace, const MissionSummary& summary,
                  const PrimitivePoolView& pool, const PinholeIntrinsics& intrinsics, double viewing_distance,
                  std::string* error) {
  bool all_ok = true;
  std::string first_error;
  auto note = [&](bool ok_step, const std::string& message) {
    if (!ok_step) {
      all_ok = false;
      if (first_error.empty()) first_error = message;
    }
  };
  auto file = [&](const char* name) { return (fs::path(dir) / name).string(); };
  std::string e;

  note(write_text(file("summary.json"), summary_json(summary), &e), e);

  // PLY: one vertex per primitive, colour by sigma, sigma and the provisional flag (primitive_flags::kProvisional:
  // no view has constrained its depth yet) as extra properties.
  {
    const SigmaScale scale = sigma_scale(pool, summary.sigma_target);
    std::ostringstream ply;
    ply << "ply\nformat ascii 1.0\ncomment vantage primitives, colour by sigma (blue " << scale.lo << ", red "
        << scale.hi << " units, log scale)\nelement vertex " << pool.size()
        << "\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\n"
           "property float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nproperty float sigma\n"
           "property uchar provisional\nend_header\n";
    for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
      if (!pool.is_alive(i)) continue;
      const Primitive& p = pool[i];
      const double sigma = primitive_sigma(p.Sigma_world);
      const Rgb c = heat(scale.t(sigma));
      ply << static_cast<float>(p.X_world.x()) << ' ' << static_cast<float>(p.X_world.y()) << ' '
          << static_cast<float>(p.X_world.z()) << ' ' << p.normal_world.x() << ' ' << p.normal_world.y() << ' '
          << p.normal_world.z() << ' ' << int(c.r) << ' ' << int(c.g) << ' ' << int(c.b) << ' ' << static_cast<float>(sigma)
          << ' ' << ((p.flags & primitive_flags::kProvisional) != 0 ? 1 : 0) << '\n';
    }
    note(write_text(file("model.ply"), ply.str(), &e), e);
  }

  note(write_uncertainty_png(file("uncertainty.png"), pool, intrinsics, viewing_distance, summary.sigma_target, &e), e);

  // Plot data.
  const GridGeometry& geo = trace.geometry;
  note(write_text(file("cost_first.dat"), grid_data(geo, trace.first_cost), &e), e);
  note(write_text(file("cost_final.dat"), grid_data(geo, trace.final_cost), &e), e);
  {
    std::vector<GridCell> occupied;
    for (std::int32_t i = 0; i < geo.cell_count(); ++i) {
      if (static_cast<std::size_t>(i) < trace.free.size() && trace.free[static_cast<std::size_t>(i)] == 0) {
        occupied.push_back(geo.cell_at(i));
      }
    }
    note(write_text(file("occupied.dat"), cells_data(geo, occupied, "x y k: occupied cells"), &e), e);
  }
  note(write_text(file("initial.dat"), cells_data(geo, trace.initial_cells, "x y k: initial views"), &e), e);
  note(write_text(file("path.dat"), cells_data(geo, trace.path, "x y k: executed path"), &e), e);
  {
    std::vector<GridCell> nbvs;
    for (const ReplanRecord& r : trace.replans) nbvs.push_back(r.nbv);
    note(write_text(file("nbv.dat"), cells_data(geo, nbvs, "x y k: NBV of plan k"), &e), e);
    std::vector<GridCell> first_plan_captures;
    for (const ImageRecord& im : trace.images) {
      if (im.nbv_iteration == 1) first_plan_captures.push_back(im.cell);
    }
    note(write_text(file("first_path.dat"), cells_data(geo, first_plan_captures, "x y k: images of plan 1"), &e), e);
  }
  {
    std::ostringstream d;
    d << "# image average_sigma utility nbv_iteration coverage(-1: not evaluated)\n";
    for (const ImageRecord& im : trace.images) {
      d << im.image << ' ' << im.average_sigma << ' ' << im.utility << ' ' << im.nbv_iteration << ' ' << im.coverage
        << '\n';
    }
    note(write_text(file("performance.dat"), d.str(), &e), e);
    std::ostringstream r;
    r << "# image reason utility_after_predict average_sigma_at_image\n";
    for (const ReplanRecord& rp : trace.replans) {
      double sigma = trace.images.empty() ? 0.0 : trace.images.front().average_sigma;
      for (const ImageRecord& im : trace.images) {
        if (im.image <= rp.at_image) sigma = im.average_sigma;
      }
      r << rp.at_image << " \"" << to_string(rp.reason) << "\" " << rp.utility_after << ' ' << sigma << '\n';
    }
    note(write_text(file("replans.dat"), r.str(), &e), e);
  }
  const double half = 0.5 * geo.cells_per_side * geo.cell_size_m;
  std::ostringstream gp;
  gp << "# vantage mission report: gnuplot report.gp\n"
     << "set terminal pngcairo size 1500,700 font ',10'\n"
     << "set output 'grid.png'\n"
     << "set multiplot layout 1,2 title 'Grid: cost (0 best), occupied cells, initial views, NBVs, path (" << summary.planner
     << ")'\n"
     << "set size ratio -1\nset xrange [" << geo.center_xy.x() - half << ":" << geo.center_xy.x() + half << "]\n"
     << "set yrange [" << geo.center_xy.y() - half << ":" << geo.center_xy.y() + half << "]\n"
     << "set palette defined (0 'blue', 0.5 'yellow', 1 'red')\nset key below\n"
     << "set cblabel 'log10 cost (cost = 1/F scaled to [0,1]; low = good view)'\n"
     << "lc(c) = log10(c > 1e-9 ? c : 1e-9)\n"
     << "set title 'first evaluation, first plan'\n"
     << "plot 'cost_first.dat' using 1:2:(lc($3)) with image notitle, "
     << "'occupied.dat' using 1:2 with points pt 5 ps 0.8 lc rgb 'black' title 'occupied', "
     << "'first_path.dat' using 1:2 with linespoints pt 7 ps 0.5 lc rgb 'white' title 'images of plan 1', "
     << "'initial.dat' using 1:2 with points pt 9 ps 2 lc rgb 'green' title 'initial views', "
     << "'nbv.dat' every ::0::0 using 1:2 with points pt 3 ps 2.5 lw 2 lc rgb 'magenta' title 'NBV 1'\n"
     << "set title 'final evaluation, executed path'\n"
     << "plot 'cost_final.dat' using 1:2:(lc($3)) with image notitle, "
     << "'occupied.dat' using 1:2 with points pt 5 ps 0.8 lc rgb 'black' title 'occupied', "
     << "'path.dat' using 1:2 with lines lw 1.5 lc rgb 'white' title 'path', "
     << "'initial.dat' using 1:2 with points pt 9 ps 2 lc rgb 'green' title 'initial views', "
     << "'nbv.dat' using 1:2 with points pt 3 ps 2 lw 2 lc rgb 'magenta' title 'NBVs', "
     << "'nbv.dat' using 1:2:(sprintf('%d',$3)) with labels offset 1,1 tc rgb 'magenta' notitle\n"
     << "unset multiplot\n"
     << "reset\n";
  if (!trace.images.empty()) {  // no image after the initial pair: no curve to draw
    gp
     << "set terminal pngcairo size 1000,800 font ',10'\n"
     << "set output 'performance.png'\n"
     << "set multiplot layout 2,1\n"
     << "set xlabel 'images'\nset grid\nset key top right\n"
     << "set ylabel 'average sigma (units)'\nset logscale y\n"
     << "set arrow from graph 0, first " << summary.sigma_target << " to graph 1, first " << summary.sigma_target
     << " nohead dt 2 lc rgb 'gray'\n"
     << "plot 'performance.dat' using 1:2 with lines lw 2 title 'average sigma', "
     << "'replans.dat' using 1:4 with points pt 7 ps 1 lc rgb 'red' title 'replan'\n"
     << "unset arrow\nunset logscale y\n"
     << "set ylabel 'utility U (units^6)'\n"
     << "plot 'performance.dat' using 1:3 with lines lw 2 title 'U(M_{nu*}, M)', "
     << "'replans.dat' using 1:3 with points pt 7 ps 1 lc rgb 'red' title 'replan (U after PredictModel)'\n"
     << "unset multiplot\n";
  }
  note(write_text(file("report.gp"), gp.str(), &e), e);
  std::string quoted;  // single-quoted for the shell
  for (const char c : dir) quoted += (c == '\'') ? std::string("'\\''") : std::string(1, c);
  const std::string command = "cd '" + quoted + "' && gnuplot report.gp > gnuplot.log 2>&1";
  const int rc = std::system(command.c_str());
  note(rc == 0, file("report.gp") + ": gnuplot failed (exit " + std::to_string(rc) + ", see gnuplot.log); grid.png and "
                                    "performance.png not written");
  if (!all_ok) *error = first_error;
  return all_ok;
}

}  // namespace vantage::simtarget
