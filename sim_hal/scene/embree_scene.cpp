#include "sim_hal/scene/embree_scene.hpp"

#include <cmath>
#include <cstring>
#include <limits>

#include "sim_hal/sim_error.hpp"

namespace vantage::sim {

namespace {

// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5), in double.
Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + ab * (d1 / (d1 - d3));
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  }
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

struct PointQueryState {
  const TriangleMesh* mesh;
  Eigen::Vector3d query;
  ClosestPoint best;
};

bool point_query_callback(RTCPointQueryFunctionArguments* args) {
  auto* state = static_cast<PointQueryState*>(args->userPtr);
  const auto& tri = state->mesh->triangles[args->primID];
  const Eigen::Vector3d q = closest_on_triangle(state->query, state->mesh->vertices[tri[0]].cast<double>(),
                                                state->mesh->vertices[tri[1]].cast<double>(),
                                                state->mesh->vertices[tri[2]].cast<double>());
  const double d = (q - state->query).norm();
  if (d < args->query->radius && (!state->best.found || d < state->best.distance)) {
    state->best.found = true;
    state->best.distance = d;
    state->best.point = q;
    state->best.triangle = args->primID;
    args->query->radius = static_cast<float>(d);
    return true;  // the query radius shrank
  }
  return false;
}

}  // namespace

EmbreeScene::EmbreeScene(TriangleMesh mesh) : mesh_(std::move(mesh)) {
  if (mesh_.triangles.empty()) throw SimError("embree scene: empty mesh");
  const std::size_t vertex_count = mesh_.vertices.size();
  for (const auto& t : mesh_.triangles) {
    for (std::uint32_t i : t) {
      if (i >= vertex_count) throw SimError("embree scene: triangle index out of range");
    }
  }
  corner_normals_ = smooth_corner_normals(mesh_, kSmoothCreaseAngleRad);
  device_ = rtcNewDevice("threads=1");
  if (device_ == nullptr) throw SimError("embree scene: rtcNewDevice failed");
  scene_ = rtcNewScene(device_);
  rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
  RTCGeometry geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                               3 * sizeof(float), vertex_count));
  auto* indices = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(
      geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(std::uint32_t), mesh_.triangles.size()));
  if (vertices == nullptr || indices == nullptr) {
    rtcReleaseGeometry(geometry);
    rtcReleaseScene(scene_);
    rtcReleaseDevice(device_);
    throw SimError("embree scene: buffer allocation failed");
  }
  for (std::size_t i = 0; i < vertex_count; ++i) {
    std::memcpy(vertices + 3 * i, mesh_.vertices[i].data(), 3 * sizeof(float));
  }
  for (std::size_t t = 0; t < mesh_.triangles.size(); ++t) {
    std::memcpy(indices + 3 * t, mesh_.triangles[t].data(), 3 * sizeof(std::uint32_t));
  }
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(scene_, geometry);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(scene_);
  if (rtcGetDeviceError(device_) != RTC_ERROR_NONE) {
    rtcReleaseScene(scene_);
    rtcReleaseDevice(device_);
    throw SimError("embree scene: scene build failed");
  }
}

EmbreeScene::~EmbreeScene() {
  rtcReleaseScene(scene_);
  rtcReleaseDevice(device_);
}

double EmbreeScene::first_hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                              std::uint32_t* triangle) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh;
  rh.ray.org_x = static_cast<float>(origin.x());
  rh.ray.org_y = static_cast<float>(origin.y());
  rh.ray.org_z = static_cast<float>(origin.z());
  rh.ray.dir_x = static_cast<float>(direction.x());
  rh.ray.dir_y = static_cast<float>(direction.y());
  rh.ray.dir_z = static_cast<float>(direction.z());
  rh.ray.tnear = 0.0f;
  rh.ray.tfar = std::numeric_limits<float>::infinity();
  rh.ray.time = 0.0f;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene_, &context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::numeric_limits<double>::infinity();
  if (triangle != nullptr) *triangle = rh.hit.primID;
  return rh.ray.tfar;
}

bool EmbreeScene::occluded(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double epsilon) const {
  const Eigen::Vector3d delta = to - from;
  const double length = delta.norm();
  if (!(length > 2.0 * epsilon)) return false;
  const Eigen::Vector3d direction = delta / length;
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay ray;
  ray.org_x = static_cast<float>(from.x());
  ray.org_y = static_cast<float>(from.y());
  ray.org_z = static_cast<float>(from.z());
  ray.dir_x = static_cast<float>(direction.x());
  ray.dir_y = static_cast<float>(direction.y());
  ray.dir_z = static_cast<float>(direction.z());
  ray.tnear = static_cast<float>(epsilon);
  ray.tfar = static_cast<float>(length - epsilon);
  ray.time = 0.0f;
  ray.mask = 0xFFFFFFFFu;
  ray.id = 0;
  ray.flags = 0;
  rtcOccluded1(scene_, &context, &ray);
  return ray.tfar < 0.0f;  // Embree sets tfar to -inf on a hit
}

ClosestPoint EmbreeScene::closest_point(const Eigen::Vector3d& query, double max_distance) const {
  PointQueryState state{&mesh_, query, ClosestPoint{}};
  alignas(16) RTCPointQuery q;
  q.x = static_cast<float>(query.x());
  q.y = static_cast<float>(query.y());
  q.z = static_cast<float>(query.z());
  q.time = 0.0f;
  q.radius = static_cast<float>(std::min(max_distance, 1e30));
  RTCPointQueryContext context;
  rtcInitPointQueryContext(&context);
  rtcPointQuery(scene_, &q, &context, point_query_callback, &state);
  return state.best;
}

}  // namespace vantage::sim
