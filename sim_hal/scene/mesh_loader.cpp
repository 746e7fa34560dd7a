#include "sim_hal/scene/mesh_loader.hpp"

#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <assimp/Importer.hpp>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <memory>
#include <system_error>

#include "core/geometry/projection.hpp"
#include "core/geometry/viewpoint.hpp"
#include "sim_hal/raycast_camera.hpp"
#include "sim_hal/scene/embree_scene.hpp"
#include "sim_hal/scene/mesh_file_checks.hpp"
#include "sim_hal/sim_error.hpp"

namespace vantage::sim {

namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw SimError("mesh file '" + path + "': " + what);
}

void append_node(const aiScene& scene, const aiNode& node, const aiMatrix4x4& parent, TriangleMesh& out) {
  const aiMatrix4x4 transform = parent * node.mTransformation;
  for (unsigned m = 0; m < node.mNumMeshes; ++m) {
    const aiMesh& mesh = *scene.mMeshes[node.mMeshes[m]];
    const std::uint32_t base = static_cast<std::uint32_t>(out.vertices.size());
    for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
      const aiVector3D p = transform * mesh.mVertices[v];
      out.vertices.emplace_back(p.x, p.y, p.z);
    }
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      const aiFace& face = mesh.mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines left by the importer
      out.triangles.push_back({base + face.mIndices[0], base + face.mIndices[1], base + face.mIndices[2]});
    }
  }
  for (unsigned c = 0; c < node.mNumChildren; ++c) append_node(scene, *node.mChildren[c], transform, out);
}

}  // namespace

const char* to_string(UpAxis axis) {
  switch (axis) {
    case UpAxis::kX: return "x";
    case UpAxis::kY: return "y";
    case UpAxis::kZ: return "z";
  }
  return "?";
}

TriangleMesh load_mesh(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) fail(path, "no such file");
  if (!std::filesystem::is_regular_file(path, ec)) fail(path, "not a regular file");
  if (std::filesystem::file_size(path, ec) == 0) fail(path, "empty file");

  // Known assimp 5.2 hangs and crashes on malformed PLY and OFF: walk their structure first.
  std::string extension = std::filesystem::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension == ".ply") {
    const std::string problem = detail::check_ply_structure(path);
    if (!problem.empty()) fail(path, problem);
  } else if (extension == ".off") {
    const std::string problem = detail::check_off_structure(path);
    if (!problem.empty()) fail(path, problem);
  }

  Assimp::Importer importer;
  // Points and lines are dropped; only triangles are kept.
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  const aiScene* scene = importer.ReadFile(
      path, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_SortByPType);
  if (scene == nullptr || scene->mRootNode == nullptr) {
    std::string why = importer.GetErrorString();
    for (char& c : why) {
      if (c == '\n' || c == '\r') c = ' ';
    }
    fail(path, "cannot parse (" + why + ")");
  }
  TriangleMesh mesh;
  append_node(*scene, *scene->mRootNode, aiMatrix4x4(), mesh);
  if (mesh.triangles.empty()) fail(path, "no triangles");
  for (const auto& t : mesh.triangles) {
    for (std::uint32_t i : t) {
      if (i >= mesh.vertices.size()) fail(path, "vertex index out of range");
    }
  }
  for (const auto& v : mesh.vertices) {
    if (!v.allFinite()) fail(path, "non-finite vertex coordinate");
  }
  if (!(mesh.surface_area() > 0.0)) fail(path, "zero surface area");
  return mesh;
}

void rotate_to_z_up(TriangleMesh& mesh, UpAxis up_axis) {
  for (auto& v : mesh.vertices) {
    const Eigen::Vector3f p = v;
    switch (up_axis) {
      case UpAxis::kZ: break;
      case UpAxis::kY: v = Eigen::Vector3f(p.x(), -p.z(), p.y()); break;
      case UpAxis::kX: v = Eigen::Vector3f(p.y(), p.z(), p.x()); break;
    }
  }
}

double mean_silhouette_fraction(const TriangleMesh& mesh, double distance, const PinholeIntrinsics& intrinsics) {
  // A quarter-resolution version of the camera is plenty for an area fraction.
  PinholeIntrinsics k = intrinsics;
  const int factor = intrinsics.width_px >= 320 ? 4 : 1;
  k.width_px = intrinsics.width_px / factor;
  k.height_px = intrinsics.height_px / factor;
  k.fx_px = intrinsics.fx_px / factor;
  k.fy_px = intrinsics.fy_px / factor;
  k.cx_px = (intrinsics.cx_px + 0.5) / factor - 0.5;
  k.cy_px = (intrinsics.cy_px + 0.5) / factor - 0.5;

  const EmbreeScene scene{TriangleMesh(mesh)};
  RaycastCameraConfig camera_config;
  camera_config.intrinsics = k;
  camera_config.threads = 2;
  camera_config.shading.samples_per_axis = 1;  // only the (pixel-centre) depth is used
  const RaycastCamera camera(scene, camera_config, nullptr);
  std::vector<std::uint8_t> pixels(static_cast<std::size_t>(k.width_px) * k.height_px);
  DepthImage depth;
  double sum = 0.0;
  for (int a = 0; a < kNormalizationAzimuths; ++a) {
    const double azimuth = 2.0 * 3.14159265358979323846 * a / kNormalizationAzimuths;
    const Eigen::Vector3d eye(distance * std::cos(azimuth), distance * std::sin(azimuth), 0.0);
    Viewpoint view;
    if (!ok(look_at(eye, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &view)) ||
        !ok(camera.render(view, MutableGrayImageView{pixels.data(), k.width_px, k.height_px, k.width_px}, &depth))) {
      continue;
    }
    std::size_t hits = 0;
    for (float z : depth.camera_z) hits += std::isfinite(z) ? 1 : 0;
    sum += static_cast<double>(hits) / static_cast<double>(depth.camera_z.size());
  }
  return sum / kNormalizationAzimuths;
}

NormalizationResult normalize_for_paper_setup(TriangleMesh& mesh, const NormalizationConfig& config) {
  if (mesh.triangles.empty()) throw SimError("normalize: empty mesh");
  if (!(config.viewing_distance > 0.0) || !std::isfinite(config.viewing_distance)) {
    throw SimError("normalize: viewing_distance must be positive");
  }
  if (!(config.target_area_fraction > 0.0 && config.target_area_fraction < 1.0)) {
    throw SimError("normalize: target_area_fraction must be in (0, 1)");
  }
  if (!std::isfinite(config.fixed_scale) || config.fixed_scale < 0.0) {
    throw SimError("normalize: scale must be >= 0 (0 = fit)");
  }
  if (!ok(config.intrinsics.validate())) throw SimError("normalize: invalid intrinsics");

  rotate_to_z_up(mesh, config.up_axis);
  NormalizationResult result;
  auto recentre_and_scale = [&mesh](double factor) {
    const Eigen::AlignedBox3d box = mesh.bounds();
    const Eigen::Vector3d centre = box.center();
    for (auto& v : mesh.vertices) v = ((v.cast<double>() - centre) * factor).cast<float>();
    return centre;
  };
  const Eigen::AlignedBox3d box0 = mesh.bounds();
  const double extent = box0.diagonal().norm();
  if (!(extent > 0.0)) throw SimError("normalize: mesh has zero extent");

  if (config.fixed_scale > 0.0) {
    result.scale = config.fixed_scale;
    recentre_and_scale(config.fixed_scale);
  } else {
    // Start with the diagonal at a third of the distance, then fix the silhouette area: area ~ scale^2
    // up to perspective, so a few multiplicative steps converge.
    double scale = config.viewing_distance / 3.0 / extent;
    recentre_and_scale(scale);
    for (int iteration = 0; iteration < 4; ++iteration) {
      const double fraction = mean_silhouette_fraction(mesh, config.viewing_distance, config.intrinsics);
      if (!(fraction > 0.0)) throw SimError("normalize: the object is not visible from the viewing distance");
      const double step = std::sqrt(config.target_area_fraction / fraction);
      if (std::abs(step - 1.0) < 2e-3) break;
      recentre_and_scale(step);
      scale *= step;
    }
    result.scale = scale;
  }
  result.translation = -box0.center() * result.scale;  // approximately: box centre moves to origin
  result.mean_area_fraction = mean_silhouette_fraction(mesh, config.viewing_distance, config.intrinsics);
  return result;
}

}  // namespace vantage::sim
