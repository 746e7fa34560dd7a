// The iterated consider update (iterated_update.cpp) for four primitives at once, one per lane of AVX
// double vectors. Why: the update is a fifth of a tracked frame (core/frontend/EXPERIMENTS.md, "Session 29:
// the EKF update for four primitives per vector"), and its small products waste most of a vector when done
// one primitive at a time. Each lane repeats the scalar code's operations in the order Eigen evaluates them
// (its 3x3 * (2x3)^T product sums rows 0-1 left to right and row 2 as a0 + (a1 + a2); every other product
// left to right), without FMA, so the results are the same bits (core test).
#include <cstdint>

#include "core/frontend/iterated_update.hpp"
#include "core/frontend/update_checks.hpp"
#include "core/geometry/projection.hpp"

namespace vantage {

namespace {

// The scalar path: the reference, and the fallback off x86-64 or without AVX2.
void update_one_by_one(const ConsiderUpdateRequest* requests, int count, const Viewpoint& view,
                       const PinholeIntrinsics& intrinsics, int max_iterations, EkfStats* stats, Status* statuses) {
  for (int l = 0; l < count; ++l) {
    const ConsiderUpdateRequest& r = requests[l];
    statuses[l] = iterated_consider_update(*r.primitive, r.common, r.observation_px, view, intrinsics, r.config,
                                           max_iterations, r.at_prior, stats);
  }
}

#if defined(__x86_64__)

using Double4 = double __attribute__((vector_size(32)));
using Mask4 = long long __attribute__((vector_size(32)));

// Lane-wise select (a macro: a helper taking vectors would not inherit the target attribute).
#define VANTAGE_SELECT(mask, a, b) ((mask) ? (a) : (b))

// Per-lane states of the iteration.
enum class Lane : std::uint8_t { kIdle, kIterating, kDone, kFailed };

// C_p' = (I - KH) C_p + K B P_p for each lane's part of the common error (CommonObservationError::has_part;
// a lane without one, or idle, computes from zeros), with update_lanes4's K, H and B, in the scalar order.
__attribute__((target("avx2"), noinline)) void updated_part_lanes4(const ConsiderUpdateRequest* requests, int count,
                                                                    const bool* active, int first_active,
                                                                    const Double4 (&K)[3][2], const Double4 (&Hk)[2][3],
                                                                    const Double4 (&B)[2][2], Double4 (&out)[3][2]) {
  Double4 Cp[3][2], Pp[2][2];
  for (int l = 0; l < 4; ++l) {
    const CommonObservationError& common = *requests[l < count && active[l] ? l : first_active].common;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 2; ++j) Cp[i][j][l] = common.has_part ? common.part_cross_covariance(i, j) : 0.0;
    }
    for (int i = 0; i < 2; ++i) {
      for (int j = 0; j < 2; ++j) Pp[i][j][l] = common.has_part ? common.part_covariance_px2(i, j) : 0.0;
    }
  }
  Double4 BPp[2][2], HCp[2][2];
  for (int i = 0; i < 2; ++i) {
    for (int j = 0; j < 2; ++j) {
      BPp[i][j] = B[i][0] * Pp[0][j] + B[i][1] * Pp[1][j];
      HCp[i][j] = Hk[i][0] * Cp[0][j] + Hk[i][1] * Cp[1][j] + Hk[i][2] * Cp[2][j];
    }
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 2; ++j) {
      const Double4 part_kept = Cp[i][j] - (K[i][0] * HCp[0][j] + K[i][1] * HCp[1][j]);
      out[i][j] = part_kept + (K[i][0] * BPp[0][j] + K[i][1] * BPp[1][j]);
    }
  }
}

// requests[l] for l < count passed the input checks (active[l]); the others are idle lanes that repeat
// an active lane's inputs. Writes statuses and, for each updated lane, the primitive and its common error.
__attribute__((target("avx2"))) void update_lanes4(const ConsiderUpdateRequest* requests, int count,
                                                   const bool* active, const Viewpoint& view,
                                                   const PinholeIntrinsics& intrinsics, int max_iterations,
                                                   EkfStats* stats, Status* statuses) {
  int first_active = 0;
  while (!active[first_active]) ++first_active;
  Lane lane[4];
  Double4 S[3][3], X0[3], C[3][2], B[2][2], P[2][2], R[2][2], obs[2], pred[2], H[2][3], gate;
  for (int l = 0; l < 4; ++l) {
    lane[l] = l < count && active[l] ? Lane::kIterating : Lane::kIdle;
    const ConsiderUpdateRequest& q = requests[lane[l] == Lane::kIterating ? l : first_active];
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) S[i][j][l] = q.primitive->Sigma_world(i, j);
      X0[i][l] = q.primitive->X_world(i);
      for (int j = 0; j < 2; ++j) C[i][j][l] = q.common->cross_covariance(i, j);
    }
    for (int i = 0; i < 2; ++i) {
      obs[i][l] = q.observation_px(i);
      pred[i][l] = q.at_prior.predicted_px(i);
      for (int j = 0; j < 3; ++j) H[i][j][l] = q.at_prior.H(i, j);
      for (int j = 0; j < 2; ++j) {
        B[i][j][l] = q.common->B(i, j);
        P[i][j][l] = q.common->covariance_px2(i, j);
        R[i][j][l] = q.config.R_px2(i, j);
      }
    }
    gate[l] = q.config.gate_chi2;
  }
  // C B^T, B P_c and R_total = B P_c B^T + R, as CommonObservationError and consider_update form them.
  Double4 CB[3][2], BP[2][2], Rt[2][2];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 2; ++j) CB[i][j] = C[i][0] * B[j][0] + C[i][1] * B[j][1];
  }
  for (int i = 0; i < 2; ++i) {
    for (int j = 0; j < 2; ++j) BP[i][j] = B[i][0] * P[0][j] + B[i][1] * P[1][j];
  }
  for (int i = 0; i < 2; ++i) {
    for (int j = 0; j < 2; ++j) Rt[i][j] = (BP[i][0] * B[j][0] + BP[i][1] * B[j][1]) + R[i][j];
  }
  Double4 X[3] = {X0[0], X0[1], X0[2]};
  Double4 K[3][2], G[3][2], Hk[2][3];
  const Double4 zero = {0.0, 0.0, 0.0, 0.0};
  const int iterations = max_iterations < 1 ? 1 : max_iterations;
  constexpr double kStepSigmas = 1e-3;  // as consider_update's
  for (int iteration = 0;; ++iteration) {
    if (iteration > 0) {
      Eigen::Vector3d points[4];
      const Eigen::Vector3d* point_ptrs[4];
      Eigen::Vector2d uv[4];
      Eigen::Matrix<double, 2, 3> Hs[4];
      Status projected[4];
      for (int l = 0; l < 4; ++l) {
        points[l] = Eigen::Vector3d(X[0][l], X[1][l], X[2][l]);
        point_ptrs[l] = &points[l];
        uv[l].setZero();
        Hs[l].setZero();
      }
      project_with_jacobian_batch(point_ptrs, 4, view, intrinsics, uv, Hs, projected);
      for (int l = 0; l < 4; ++l) {
        for (int i = 0; i < 2; ++i) {
          pred[i][l] = uv[l](i);
          for (int j = 0; j < 3; ++j) H[i][j][l] = Hs[l](i, j);
        }
        if (lane[l] == Lane::kIterating && !ok(projected[l])) {
          lane[l] = Lane::kFailed;
          statuses[l] = Status::kBehindCamera;
          ++stats->rejected_inputs;
        }
      }
    }
    // innovation_gain.
    Double4 SHt[3][2], HCB[2][2], HSH[2][2];
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 2; ++j) {
        SHt[i][j] = i < 2 ? (S[i][0] * H[j][0] + S[i][1] * H[j][1]) + S[i][2] * H[j][2]
                          : S[i][0] * H[j][0] + (S[i][1] * H[j][1] + S[i][2] * H[j][2]);
      }
    }
    for (int i = 0; i < 2; ++i) {
      for (int j = 0; j < 2; ++j) {
        HCB[i][j] = H[i][0] * CB[0][j] + H[i][1] * CB[1][j] + H[i][2] * CB[2][j];
        HSH[i][j] = H[i][0] * SHt[0][j] + H[i][1] * SHt[1][j] + H[i][2] * SHt[2][j];
      }
    }
    const Double4 s00 = HSH[0][0] - 2.0 * HCB[0][0] + Rt[0][0];
    const Double4 s11 = HSH[1][1] - 2.0 * HCB[1][1] + Rt[1][1];
    const Double4 s01 = 0.5 * (HSH[0][1] + HSH[1][0]) - HCB[0][1] - HCB[1][0] + 0.5 * (Rt[0][1] + Rt[1][0]);
    const Double4 det = s00 * s11 - s01 * s01;
    const Mask4 gain_ok = (s00 > zero) & (det > zero);
    const Double4 inv_det = 1.0 / det;
    const Double4 Si00 = s11 * inv_det;
    const Double4 Si01 = -s01 * inv_det;
    const Double4 Si11 = s00 * inv_det;
    Double4 Gn[3][2], Kn[3][2];
    for (int i = 0; i < 3; ++i) {
      Gn[i][0] = SHt[i][0] - CB[i][0];
      Gn[i][1] = SHt[i][1] - CB[i][1];
      Kn[i][0] = Gn[i][0] * Si00 + Gn[i][1] * Si01;
      Kn[i][1] = Gn[i][0] * Si01 + Gn[i][1] * Si11;
    }
    const Double4 in0 = obs[0] - pred[0];
    const Double4 in1 = obs[1] - pred[1];
    Mask4 gate_ok = {-1, -1, -1, -1};
    Double4 nis = zero;
    if (iteration == 0) {
      const Double4 v0 = Si00 * in0 + Si01 * in1;
      const Double4 v1 = Si01 * in0 + Si11 * in1;
      nis = in0 * v0 + in1 * v1;
      gate_ok = nis <= gate;
    }
    Mask4 iterating = {0, 0, 0, 0};
    for (int l = 0; l < 4; ++l) {
      if (lane[l] != Lane::kIterating) continue;
      if (!gain_ok[l]) {
        lane[l] = Lane::kFailed;
        statuses[l] = Status::kNotSpd;
        ++stats->rejected_inputs;
        continue;
      }
      // The innovation the scalar update's gate tests, recorded at the same point.
      if (iteration == 0) stats->nis.record(nis[l]);
      if (!gate_ok[l]) {
        lane[l] = Lane::kFailed;
        statuses[l] = Status::kGatedOutlier;
        ++stats->gated_outliers;
      } else {
        iterating[l] = -1;
      }
    }
    // The linearization of the lanes still iterating is their latest (the covariance uses it).
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 2; ++j) {
        K[i][j] = iteration == 0 ? Kn[i][j] : VANTAGE_SELECT(iterating, Kn[i][j], K[i][j]);
        G[i][j] = iteration == 0 ? Gn[i][j] : VANTAGE_SELECT(iterating, Gn[i][j], G[i][j]);
      }
    }
    for (int i = 0; i < 2; ++i) {
      for (int j = 0; j < 3; ++j) Hk[i][j] = iteration == 0 ? H[i][j] : VANTAGE_SELECT(iterating, H[i][j], Hk[i][j]);
    }
    bool any = false;
    for (int l = 0; l < 4; ++l) any = any || lane[l] == Lane::kIterating;
    if (!any) break;
    if (iteration == iterations) {
      for (int l = 0; l < 4; ++l) {
        if (lane[l] == Lane::kIterating) lane[l] = Lane::kDone;
      }
      break;
    }
    // step = X0 + K (o - phi - H (X0 - X)) - X.
    const Double4 d0 = X0[0] - X[0];
    const Double4 d1 = X0[1] - X[1];
    const Double4 d2 = X0[2] - X[2];
    const Double4 r0 = in0 - (H[0][0] * d0 + H[0][1] * d1 + H[0][2] * d2);
    const Double4 r1 = in1 - (H[1][0] * d0 + H[1][1] * d1 + H[1][2] * d2);
    Double4 step[3];
    for (int i = 0; i < 3; ++i) {
      step[i] = (X0[i] + (Kn[i][0] * r0 + Kn[i][1] * r1)) - X[i];
      X[i] = VANTAGE_SELECT(iterating, X[i] + step[i], X[i]);
    }
    if (iteration == 0) continue;
    // mahalanobis_squared(Sigma, step) by the adjugate.
    const Double4 c00 = S[1][1] * S[2][2] - S[1][2] * S[1][2];
    const Double4 c01 = S[0][2] * S[1][2] - S[0][1] * S[2][2];
    const Double4 c02 = S[0][1] * S[1][2] - S[0][2] * S[1][1];
    const Double4 c11 = S[0][0] * S[2][2] - S[0][2] * S[0][2];
    const Double4 c12 = S[0][1] * S[0][2] - S[0][0] * S[1][2];
    const Double4 c22 = S[0][0] * S[1][1] - S[0][1] * S[0][1];
    const Double4 adj_det = S[0][0] * c00 + S[0][1] * c01 + S[0][2] * c02;
    const Double4 quadratic = c00 * step[0] * step[0] + c11 * step[1] * step[1] + c22 * step[2] * step[2] +
                              2.0 * (c01 * step[0] * step[1] + c02 * step[0] * step[2] + c12 * step[1] * step[2]);
    const Double4 limit = {kStepSigmas * kStepSigmas, kStepSigmas * kStepSigmas, kStepSigmas * kStepSigmas,
                           kStepSigmas * kStepSigmas};
    const Mask4 converged = (quadratic / adj_det) <= limit;
    any = false;
    for (int l = 0; l < 4; ++l) {
      if (lane[l] == Lane::kIterating && converged[l]) lane[l] = Lane::kDone;
      any = any || lane[l] == Lane::kIterating;
    }
    if (!any) break;
  }
  // Sigma - K G^T symmetrized (updated_covariance's short form) and C' = (I - KH) C + K B P_c.
  Double4 Sn[3][3], cross[3][2];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      const Double4 a = S[i][j] - (K[i][0] * G[j][0] + K[i][1] * G[j][1]);
      const Double4 b = S[j][i] - (K[j][0] * G[i][0] + K[j][1] * G[i][1]);
      Sn[i][j] = 0.5 * (a + b);
    }
  }
  Double4 HC[2][2];
  for (int i = 0; i < 2; ++i) {
    for (int j = 0; j < 2; ++j) HC[i][j] = Hk[i][0] * C[0][j] + Hk[i][1] * C[1][j] + Hk[i][2] * C[2][j];
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 2; ++j) {
      const Double4 kept = C[i][j] - (K[i][0] * HC[0][j] + K[i][1] * HC[1][j]);
      cross[i][j] = kept + (K[i][0] * BP[0][j] + K[i][1] * BP[1][j]);
    }
  }
  // The part of the common error kept apart, when any lane has one (in its own function, so that the
  // update's own code compiles as it did without it).
  Double4 part_cross[3][2];
  bool has_part = false;
  for (int l = 0; l < count; ++l) has_part = has_part || (active[l] && requests[l].common->has_part);
  if (has_part) updated_part_lanes4(requests, count, active, first_active, K, Hk, B, part_cross);
  for (int l = 0; l < count; ++l) {
    if (lane[l] != Lane::kDone) continue;
    const ConsiderUpdateRequest& q = requests[l];
    Eigen::Matrix3d Sigma_new;
    Eigen::Vector3d X_new;
    Eigen::Matrix<double, 3, 2> cross_new;
    for (int i = 0; i < 3; ++i) {
      X_new(i) = X[i][l];
      for (int j = 0; j < 3; ++j) Sigma_new(i, j) = Sn[i][j][l];
      for (int j = 0; j < 2; ++j) cross_new(i, j) = cross[i][j][l];
    }
    const bool lane_part = has_part && q.common->has_part;
    Eigen::Matrix<double, 3, 2> part_cross_new;
    if (lane_part) {
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 2; ++j) part_cross_new(i, j) = part_cross[i][j][l];
      }
    }
    if (!update_checks::short_form_trusted(Sigma_new, q.primitive->Sigma_world)) {
      // The short form cancelled: the scalar update, which takes the Joseph form, from the same inputs. Its
      // counts, but not its innovation, which this lane recorded already.
      EkfStats redo;
      statuses[l] = iterated_consider_update(*q.primitive, q.common, q.observation_px, view, intrinsics, q.config,
                                             max_iterations, q.at_prior, &redo);
      stats->accepted += redo.accepted;
      stats->gated_outliers += redo.gated_outliers;
      stats->rejected_inputs += redo.rejected_inputs;
      continue;
    }
    if (!X_new.allFinite() || !cross_new.allFinite() || (lane_part && !part_cross_new.allFinite())) {
      statuses[l] = Status::kNotSpd;
      ++stats->rejected_inputs;
      continue;
    }
    q.primitive->X_world = X_new;
    q.primitive->Sigma_world = Sigma_new;
    q.common->cross_covariance = cross_new;
    if (lane_part) q.common->part_cross_covariance = part_cross_new;
    ++q.primitive->observation_count;
    ++stats->accepted;
    statuses[l] = Status::kOk;
  }
}

#undef VANTAGE_SELECT

#endif  // __x86_64__

}  // namespace

void iterated_consider_update_batch(const ConsiderUpdateRequest* requests, int count, const Viewpoint& view,
                                    const PinholeIntrinsics& intrinsics, int max_iterations, EkfStats* stats,
                                    Status* statuses) {
  if (count <= 0) return;
  if (count > kUpdateBatchSize) count = kUpdateBatchSize;
  EkfStats ignored;
  EkfStats* counts = stats != nullptr ? stats : &ignored;
#if defined(__x86_64__)
  if (__builtin_cpu_supports("avx2")) {
    // consider_update's input checks, in its order, before any lane work.
    bool active[kUpdateBatchSize] = {false, false, false, false};
    bool any = false;
    for (int l = 0; l < count; ++l) {
      const ConsiderUpdateRequest& q = requests[l];
      statuses[l] = update_checks::check_inputs(*q.primitive, *q.common, q.observation_px, view, q.config, &q.at_prior);
      if (!ok(statuses[l])) {
        ++counts->rejected_inputs;
      } else {
        active[l] = true;
        any = true;
      }
    }
    if (any) update_lanes4(requests, count, active, view, intrinsics, max_iterations, counts, statuses);
    return;
  }
#endif
  update_one_by_one(requests, count, view, intrinsics, max_iterations, counts, statuses);
}

}  // namespace vantage
