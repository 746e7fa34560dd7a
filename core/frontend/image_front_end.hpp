#pragma once
// The image measurement front end: structure from motion with known camera poses, one EKF per
// primitive (paper section III). initialize() seeds the model from two images with a small baseline;
// update() tracks every visible primitive into a new image and feeds the match to ekf_update, grows
// the model where the image shows surface no primitive covers, and merges coplanar, well-estimated
// neighbours (adaptive scale). Heap-free: images are read through views, the previous frame is copied
// into an inline buffer, and all scratch space is a member.
//
// The object is large (a 1280x960 frame, per-cell tables, a table of view poses: about 5 MB); targets
// hold it in static storage, never on the stack.
#include <array>
#include <cstdint>

#include <Eigen/Core>

#include "core/common/status.hpp"
#include "core/criterion/depth_buffer.hpp"
#include "core/criterion/saliency.hpp"
#include "core/estimation/ekf.hpp"
#include "core/frontend/iterated_update.hpp"
#include "core/frontend/measurement_source.hpp"
#include "core/frontend/ncc.hpp"
#include "core/frontend/patch_search.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/image/gray_image.hpp"
#include "core/model/primitive_pool.hpp"

namespace vantage {

// Capacities. Frames up to 1280x960; seeds at least 2 px apart; the last kFrontEndMaxViews view poses
// are kept to warp patches from their creating view (older primitives are matched unwarped).
inline constexpr std::int32_t kFrontEndMaxWidth = 1280;
inline constexpr std::int32_t kFrontEndMaxHeight = 960;
inline constexpr std::int32_t kFrontEndMinSeedStride = 2;
inline constexpr std::size_t kFrontEndMaxCells =
    static_cast<std::size_t>(kFrontEndMaxWidth / kFrontEndMinSeedStride) * (kFrontEndMaxHeight / kFrontEndMinSeedStride);
inline constexpr std::size_t kFrontEndMaxViews = 1024;
inline constexpr std::int32_t kFrontEndMaxHalfWindow = 24;
inline constexpr std::size_t kFrontEndMaxEpipolarSamples = 2048;
// The largest FrontEndConfig::epipolar_guard_fraction: the guard holds at most 16 knots a range length.
inline constexpr double kMaxEpipolarGuardFraction = 4.0;
// FrontEndConfig::match_floor_tilt_power: at most this power, and the tilt's cosine taken as at least
// kMatchFloorMinCos (78 degrees), so a grazing view's floor grows at most 0.2^-k times.
inline constexpr double kMaxMatchFloorTiltPower = 4.0;
inline constexpr double kMatchFloorMinCos = 0.2;
// FrontEndConfig::deformation_error_power: at most this power (the singular values' ratio less one).
inline constexpr double kMaxDeformationErrorPower = 8.0;
// The deformation error's stretch ratio is taken as at most this (about 84 degrees of foreshortening), where a
// nearly singular warp would make it unbounded (warp_stretch_ratio's cap).
inline constexpr double kMaxDeformationStretchRatio = 10.0;
// Primitives whose normal uncertainty is tracked (pool indices beyond it get the facing-camera prior).
inline constexpr std::size_t kFrontEndMaxPrimitives = kDefaultPrimitiveCapacity;
// A normal's local plane fit reads the cells within this many of its own (FrontEndConfig::normal_fit_ring_cells).
inline constexpr std::int32_t kFrontEndMaxNormalFitRing = 2;
inline constexpr std::size_t kFrontEndMaxNormalFitNeighbours =
    static_cast<std::size_t>((2 * kFrontEndMaxNormalFitRing + 1) * (2 * kFrontEndMaxNormalFitRing + 1) - 1);

struct FrontEndConfig {
  // Low-pass every frame before anything reads it (core/image/binomial_smooth.hpp, 3x3 binomial), so the
  // matcher resamples a band-limited image: seeds, templates and matches all see the smoothed frame. Off
  // by default: the matches are no more accurate with it while their fit covariances shrink, so the filter
  // gets more over-confident (the missions' gate diagnostics; the consistency test's bunny NEES triples at
  // 320x240) (EXPERIMENTS.md, "Pre-smoothing").
  bool presmooth = false;
  // Seeds: one candidate pixel per seed_stride_px x seed_stride_px cell, if its patch has contrast.
  std::int32_t seed_stride_px = 4;
  float min_texture_stddev_gray = 6.0f;
  // Matching: NCC threshold, uniqueness ratio, cap of the 3-sigma search window (px each side).
  float ncc_min = 0.8f;
  // New primitives have no prior to gate a wrong match: they need a stronger NCC peak.
  float spawn_ncc_min = 0.9f;
  float uniqueness_ratio = 0.95f;
  std::int32_t max_search_half_window_px = 12;
  // A primitive whose prior 3-sigma ellipse (H Sigma H^T's largest semi-axis) lies within this many pixels
  // of its prediction is matched by the subpixel fit from the prediction, the window searched only when
  // that fit fails (patch_search.hpp, WindowQuery::direct_fit; EXPERIMENTS.md, "Seventh round"). 0: always
  // search.
  double direct_fit_max_px = 1.0;
  // Gauss-Newton steps of the photometric subpixel refinement after the parabola fit (0: parabola only).
  int subpixel_iterations = 3;
  // A tracked match whose subpixel fit did not converge (its last step not below 0.01 px) is not used:
  // MatchConfig::require_converged_fit, counted as a no_subpixel failure. It checks the window search's fit
  // (the direct fit from the prediction always had to converge) and the refit with the template of a new
  // photometric normal (refine_normal_photometric): a refit that does not settle drops that estimate, and the
  // window search's match stands (FrontEndStats::photometric_refits_unconverged). Off by default. With
  // subpixel_iterations = 6, every scene's tracked RMS error falls, as does the bunny's NEES, and the missions
  // gain precise verified coverage (level coverage at 600 images, -4.6 points at 270). The planes' NEES falls
  // below its bands (EXPERIMENTS.md, "Session 30"); with match_sigma_floor_rad 1.4e-4 the 640x480 plane is in
  // band again, but the missions lose verified coverage ("Session 31").
  bool require_converged_fit = false;
  // The scene's depth range along the optical axis (scene units): bounds the epipolar search. The
  // defaults are close to the paper's scene seen from 40 units, whose bunny spans camera z 22.3..55.9 on the
  // integration test's views: a seed whose true match lies outside the range can take a wrong one inside
  // it (EXPERIMENTS.md, "Why tracked matches fail"). The missions derive theirs from the grid.
  double depth_min = 25.0;
  double depth_max = 55.0;
  // The epipolar search looks this fraction of the range's inverse-depth span past both of its ends (the
  // far side at most to infinity) and spawns nothing when the best peak lies there, so a surface beyond
  // the range is not spawned at a wrong depth inside it (EpipolarQuery::guard_fraction; EXPERIMENTS.md,
  // "Session 22"). 0: the range alone, as before.
  double epipolar_guard_fraction = 0.25;
  // The left-right check of a new primitive's match: the patch found in the other image is searched back
  // along its own epipolar line in the seed's image, and the seed is spawned only when that search finds
  // a unique peak within this many pixels of where the seed's patch lies (the seed, moved by the match's
  // subpixel offset from the pixel the back search starts at). A wrong peak of a repetitive texture, or
  // a patch across a depth edge whose layers slide apart, matches back elsewhere. A back search with no
  // room in the seed's image cannot judge and lets the seed through. Counted in
  // FrontEndStats::seeds_rejected_back_match. 0: off. The default since session 44 is 1 px: over 22 paired
  // missions the confirmed primitives' RMS error falls by a fifth (0.115 -> 0.095 at 600 images, 0.112 ->
  // 0.087 at 270) and those more than a unit off by an eighth, coverage +1.3 / +1.8 points (standard errors
  // 0.7 / 1.4); in the consistency test every scene's primitives are more accurate, and the 640x480 plane's
  // NEES moves just below its band, to the cautious side (2.978 -> 2.899): the floor was calibrated with the
  // refused seeds (EXPERIMENTS.md, "Session 42" and "Session 44").
  double spawn_back_match_max_px = 1.0;
  // A new primitive whose neighbours fit no plane (the spawn's normal fit fails, so it would keep the facing
  // prior) is erased before anything uses it: its seed lies on a depth edge, on relief the fit's chi^2 test
  // refuses, or alone. Counted in FrontEndStats::seeds_rejected_no_plane_fit. Off by default: on the
  // 640x480 bunny those seeds' mean NEES is about 87, and without them the all-primitive row falls 11.6 ->
  // 8.5. Over 22 paired missions the confirmed primitives' RMS falls by a third (0.095 -> 0.063 at 600
  // images) and those more than a unit off by two thirds, with coverage level at 600 images but 4.2 points
  // lower at 270 (EXPERIMENTS.md, "Session 45").
  bool spawn_requires_plane_fit = false;
  // The Mahalanobis gate of the EKF, and the fixed image measurement covariance R (px^2). R sizes the
  // search windows; it is also each match's R when adaptive_R is off.
  EkfConfig ekf;
  // adaptive_R: each match's R is the least-squares covariance of its photometric subpixel fit (residual
  // variance times the shift block of (J^T J)^-1) plus the floor's covariance for what the fit does not
  // see (interpolation, warp and lattice effects). The seed pixel of a new primitive defines the point it
  // stands for, so its own observation gets the floor alone.
  bool adaptive_R = true;
  // Iterations of the iterated EKF update (core/frontend/iterated_update.hpp); 1 is the plain EKF.
  int ekf_iterations = 5;
  // The floor's standard deviation as an angle (rad): per axis it is this times the focal length in
  // pixels, so every resolution of a camera gets the same floor (0.087 px at the paper's 640x480 camera,
  // fy 579 px; 0.043 px at 320x240). The error it covers scales with the scene in the image, not with the
  // pixel: the plane's per-match NEES read 0.85 at 320x240 and 1.59 at 640x480 with one 0.05 px floor, and
  // 1.02 at 640x480 with 1.7e-4 rad (EXPERIMENTS.md, "The match floor as an angle (session 12)"). 1.7e-4
  // until session 34; 1.5e-4 since, with max_match_sigma_rad and normal_spawn_residual_floor on: the limit
  // leaves out the matches of poorly known normals that the higher floor covered for, and at 1.5e-4 the
  // facing 640x480 plane, the calibration scene, is in its band on both rows (EXPERIMENTS.md, "Session 34").
  double match_sigma_floor_rad = 1.5e-4;
  // A tracked match's floor grows with the surface's tilt: its standard deviation is match_sigma_floor_rad /
  // cos^k, cos the smaller of |n . line of sight| in the creating view and in this view (the estimated
  // normal; at least kMatchFloorMinCos), k this power. The matches' shared error grows with the tilt
  // (EXPERIMENTS.md, "Session 20", "Session 31"). 0: off, the default; a new primitive's seed match keeps
  // the plain floor (its normal is not known yet).
  double match_floor_tilt_power = 0.0;
  // A tracked match whose modelled covariance (R with the warp covariance, plus the reference patch's
  // common error) has a mean standard deviation sqrt(trace / 2) above this angle times the focal length
  // is not used: counted as TrackFailureCounts::too_uncertain, the primitive left as it was (not flagged,
  // no rejection counted: an unconfirmed new primitive is not erased for it). 0: off. In [0, 0.01). Such matches are mostly those of poorly
  // known normals, and their errors are not Gaussian: in the consistency test the ones with sd >= 0.25 px
  // read mean NEES / 2 of 14-16 against 1-2 for the rest. At 4.3e-4 (0.25 px at the paper's 640x480
  // camera) the bunny's mean NEES, all primitives, 7.61 -> 3.88 (320x240, the gross failure gone) and the
  // tracked primitives' RMS surface error falls on every scene; over 22 missions the share of precise
  // primitives within 3 sigmas of the surface rises 6.9 / 8.1 points at 600 / 270 images (22 of 22), with
  // coverage -1.1 / -2.3 (standard errors 0.8 / 1.7); alone it takes the facing 640x480 plane's NEES below
  // its band (2.956 -> 2.691) (EXPERIMENTS.md, "Session 27"). The default since session 34: 7e-4 (0.41 px
  // at 640x480), with match_sigma_floor_rad at 1.5e-4 and normal_spawn_residual_floor at 1. Against the
  // default before (off, 1.7e-4, 0) the plane's and the bunny's mean NEES move toward 3 (the bunny's, all
  // primitives, 7.61 -> 4.48 at 320x240), the 640x480 plane stays in its band, and over 44 missions at
  // 600 images coverage +0.9 and verified coverage +0.7 points, at 270 images +4.1 / +4.1 (EXPERIMENTS.md,
  // "Session 34"). Lower limits refuse too many of the bunny's matches (5e-4 with these floors: its match
  // rate 0.45 at 320x240, below the 0.5 its accuracy case checks).
  double max_match_sigma_rad = 7e-4;
  // The fit covariance with the spatial correlation of the fit's residuals (core/frontend/
  // match_covariance.hpp) instead of the white-residual one. Needs adaptive_R. Off: on the consistency
  // test it made the plane more conservative (NEES 2.66 -> 2.26) and let a wrong match on the bunny pass
  // the gate, and it costs about 12,600 instructions a match (README, "Consistency").
  bool correlated_fit_covariance = false;
  // Triangulations whose largest standard deviation exceeds this (scene units) carry no usable depth.
  double max_initial_sigma = 10.0;
  // The normal's uncertainty in R (see README, "Normal uncertainty"): a primitive's normal has a tilt
  // variance (rad^2 per axis); through the warp it displaces the match, and that covariance is added to
  // R. A normal that only faces the creating camera has facing_normal_tilt_variance: the in-plane
  // components of a unit normal drawn from the visible hemisphere with density proportional to cos
  // (surfaces show in proportion to their projected area) have variance 1/4 each.
  bool model_normal_uncertainty = true;
  double facing_normal_tilt_variance = 0.25;
  // The same for a new primitive's two-view match (with model_normal_uncertainty): the seed patch is
  // matched unwarped, i.e. as if the surface faced the reference camera, so the facing prior's tilt
  // variance displaces that match too; it is added to the match's R before triangulating. Off: it makes a
  // new primitive's first re-observation consistent whatever the spawn baseline, but the sim mission got
  // worse with it (EXPERIMENTS.md, "Why the mission gates").
  bool model_spawn_normal_uncertainty = false;
  // Photometric normal (core/frontend/photometric_normal.hpp): a matched primitive whose normal's tilt
  // variance exceeds photometric_normal_min_tilt_variance, and whose warp covariance (the normal's
  // uncertainty in this match) outweighs the match's own R, gets its normal estimated from the warp
  // between its creating view and this one, and is matched again with the template warped by it. Needs
  // adaptive_R and subpixel_iterations >= 1.
  bool photometric_normal = true;
  double photometric_normal_min_tilt_variance = 0.01;
  // A tracked primitive whose warped template would have fewer than half its pixels inside the stored
  // patch (TrackFailureCounts::template_masked: a view far from the creating one) is matched instead by
  // warping the image: the photometric normal's fit from the prediction over all 49 reference pixels, its
  // shift covariance (sandwich form, the normal's tilt marginalized, scaled by the samples per image pixel)
  // as the match's covariance, its normal adopted when better known. Off by default: over 22 missions it
  // raises the coverage from 64.8 % to 67.0 %, but the integration test's NEES moves away from its band on
  // four of its eight rows (EXPERIMENTS.md, "Matching masked templates by the inverse warp", "The inverse
  // warp's matches, one by one (session 14)"). Needs photometric_normal's requirements.
  bool inverse_warp_masked = false;
  // The NCC an inverse-warp match must reach. The default is the tracker's ncc_min; the fit has no
  // uniqueness test, but no single stricter value suits every scene (EXPERIMENTS.md, "The inverse warp's
  // matches, one by one (session 14)").
  float inverse_warp_ncc_min = 0.8f;
  // The reference patch's own pixel noise shifts the feature every match of a primitive looks for by the
  // same amount: an error common to all its observations, carried in the consider form of the update
  // (core/frontend/iterated_update.hpp) instead of averaging away. Its covariance is half the fit
  // covariance of the primitive's first match (the same camera gives every frame the same noise, and
  // the fit's residual holds both frames' noise), and half of each later match's fit covariance is its
  // own, independent part. Needs adaptive_R.
  bool model_template_noise = true;
  // The view-correlated match error (EXPERIMENTS.md, "Session 38"): besides the patch's noise, a match of
  // the same patch is displaced by an appearance error that changes slowly with the viewpoint (resampling
  // and aliasing of the same texture, the patch's non-planarity and shading at nearly the same geometry),
  // so consecutive matches share it and only matches from well-separated views average it away. Modelled
  // as a second common error s beside the patch noise c (core/frontend/iterated_update.hpp), with
  // covariance view_correlated_error_scale x P_c and correlation exp(-angle / view_correlation_deg)
  // between two views (the angle at the primitive between the cameras); its cross-covariance with the
  // position error decays by that factor between updates. It enters the new primitive's two-view match
  // too. Needs model_template_noise. 0: off (the default; the owner's table, core/frontend/README.md).
  double view_correlated_error_scale = 0.0;
  double view_correlation_deg = 30.0;
  // The deformation error (EXPERIMENTS.md, "Session 39"): where the warp stretches the reference patch
  // unevenly (an oblique surface seen from a new angle), the resampled template misses the texture's detail
  // and a match is displaced by an error that nearby views share. It is the view-correlated error s above
  // with covariance deformation_error_scale x (r - 1)^deformation_error_power x the match floor, r the
  // ratio of the warp's singular values (1: no deformation; the scene's own scale, so a plane seen nearly
  // head-on gets almost none and the oblique bunny most), correlated as above over view_correlation_deg.
  // Its cross-covariance follows the AR(1) rule with a varying variance (scaled by the ratio of the
  // standard deviations). It is the model's error, not the match's, so max_match_sigma_rad does not count
  // it. Needs model_template_noise. 0: off (the default; the owner's table, core/frontend/README.md).
  double deformation_error_scale = 0.0;
  double deformation_error_power = 3.0;
  // A new primitive rests on one two-view match. The first image after its creation must confirm it:
  // when it is not predicted in view there (a wrong match behind the surface stays hidden by the depth
  // buffer for good), or its match fails or is gated, it is erased rather than kept with an estimate
  // nothing else supports (a wrong epipolar match, a patch across a depth edge). Counted in
  // FrontEndStats::unconfirmed_erased.
  bool confirm_spawns = true;
  // Track loss: a primitive whose last max_rejected_in_a_row predicted-in-view observations were all
  // failed matches or gated is erased (FrontEndStats::gated_erased), so augmentation re-spawns its region
  // fresh. Failed matches count too: a badly initialized primitive predicts far from its feature, beyond
  // the capped search window, so it mostly fails to match rather than being gated. 0: never, at most 255.
  // Off by default: with 3 the bunny mission lost coverage (README, "Track loss").
  std::uint32_t max_rejected_in_a_row = 0;
  // Unconsumed primitives: one whose last unconsumed_after_rejections predicted-in-view observations were
  // all failed matches or gated gets primitive_flags::kUnconsumed (kept, not erased) until an accepted
  // update clears it; the criterion leaves it out of F and the planner out of U, since images do not
  // consume its uncertainty (core/planning/README.md, "Why coverage stalls"). 0: never, at most 255.
  std::uint32_t unconsumed_after_rejections = 3;
  // Re-initialization of unsearchable primitives: an unconsumed primitive (above) whose predicted 3-sigma
  // ellipse no longer fits the capped search window (max_search_half_window_px) at its latest rejection
  // is erased, so augmentation re-spawns its region. The search cannot cover where its feature may be,
  // so no later image can correct it (a "ghost" from a small-baseline spawn); a well-estimated primitive
  // that misses matches (appearance, occlusion) keeps a small window and is only flagged.
  // FrontEndStats::unsearchable_erased, UpdateReport::gated_erased. Needs unconsumed_after_rejections > 0.
  bool erase_unsearchable = true;
  // Warp the reference patch when the plane-induced map differs from identity by more than this
  // (Frobenius norm of A - I).
  double warp_min_deviation = 0.05;
  // A primitive faces a camera when cos(normal, direction to the camera) exceeds this.
  double min_facing_cos = 0.05;
  // Whole-image checks: below this standard deviation (gray levels) an image is constant; above this
  // fraction of clipped pixels (0 or 255) it is black or saturated.
  float min_image_stddev_gray = 2.0f;
  float max_clipped_fraction = 0.9f;
  // Occlusion: primitives are splatted into a depth buffer pushed back by occlusion_sigmas standard
  // deviations along the ray and tested pulled forward by as many, so only an occluder in front beyond
  // both uncertainties hides a primitive.
  bool occlusion_enabled = true;
  double occlusion_sigmas = 3.0;
  // h(P) of new primitives (core/criterion/saliency.hpp).
  SaliencyParams saliency;
  // Normal refit from well-estimated neighbours when a primitive reaches n, 2n, 4n and 8n EKF updates.
  std::uint32_t normal_refit_observations = 3;
  // The refit's tilt variance is at least this times its residual variance over its points' in-plane
  // spread (PlaneFitConfig::residual_tilt_floor; 0: off). >= 0. Off by default: at 1, over 22 missions at
  // 600 images verified coverage +1.7 points (standard error 0.6, 18 of 22) with the 640x480 plane still in
  // its band, but at 270 images, the paper's budget, the confirmed primitives' RMS error +0.027 (0.008)
  // and coverage -2.5 (1.9) (EXPERIMENTS.md, "Session 25").
  double normal_refit_residual_floor = 0.0;
  // A refit replaces a normal from the spawn's plane fit or the facing prior whatever tilt variance that
  // claims (normal_refit_replaces). The spawn's fit reads two-view depths and claims too little: in a
  // 600-image mission a third of the tracked primitives kept it for life, 14 degrees off while claiming
  // about 3. Off by default: with the floor at 1, over the same 22 missions verified coverage +2.0 points
  // (standard error 0.5, 17 of 22), but the 640x480 plane's NEES falls below its band (all 2.913 in
  // [2.943, 3.057]): the consistency test of issue 5 item 6 and the missions disagree.
  bool refit_supersedes_spawn_fit = false;
  // The spawn's plane fit along the rays claims a tilt variance of at least this times its residual
  // variance over its points' in-plane spread (RayPlaneFitConfig::residual_tilt_floor; 0: off). >= 0. A
  // new primitive beside tracked neighbours gets a plane through well-known points: its chi^2 scaling sees
  // no noise, while the surface at the patch's scale differs from that plane; in a 600-image mission the
  // spawn's fits were 14 degrees off claiming 3.6 (angle^2 / variance 23). A floored claim stays below
  // facing_normal_tilt_variance (RayPlaneFitConfig::floored_claim_limit), so a fit still replaces the prior.
  // Measured before it was the default: at 1 with normal_refit_residual_floor at 1, over 22 missions at
  // 600 images verified coverage +2.6 points (standard error 0.5, 21 of 22), at 270 images level (+0.0,
  // 1.2) with coverage -1.9 (1.3); the 320x240 bunny's tracked NEES 6.01 -> 4.83, but the 640x480 plane's
  // rises out of its band (2.963 -> 3.193). Alone: 600 images +1.4 (0.6), 270 coverage -3.3 (1.8), the
  // 640x480 plane in its band (3.000) and the bunny's rows 5.11 / 5.46 (EXPERIMENTS.md, "Session 26"). 1 by
  // default since session 34, with max_match_sigma_rad at 7e-4 and the floor at 1.5e-4 (see there).
  double normal_spawn_residual_floor = 1.0;
  // The neighbours a normal's local plane fit reads (at spawn and at each refit): the nearest primitive of
  // every cell within this many cells, 1..kFrontEndMaxNormalFitRing (2: the 5 x 5 cells around, 24
  // neighbours). 1 (the 8 adjacent cells) left a third of the bunny's tracked primitives at 640x480 with
  // normals more than 20 degrees off, and they held half its NEES excess (EXPERIMENTS.md, "The normal fit's
  // neighbourhood (session 12)").
  std::int32_t normal_fit_ring_cells = 2;
  // A new primitive's normal from its neighbours fitted along the spawn camera's rays
  // (fit_plane_normal_along_rays, core/frontend/surface_fit.hpp): the neighbours' depth errors weighted
  // by their variances and a noisy plane accepted by its chi^2, with a tilt variance to match; its radius
  // stays the facing footprint. Off: the scatter fit (fit_plane_normal), which refuses any neighbourhood
  // whose depth scatter is not thin against its spread (at 640x480 most new normals stayed on the facing
  // prior), and a radius stretched by the incidence. Refits of tracked primitives use the scatter fit
  // either way: their errors no longer lie along one camera's rays (EXPERIMENTS.md, "Session 21").
  bool spawn_normal_fit_along_rays = true;
  // Adaptive scale (see README): neighbours in the image merge when both have at least
  // merge_min_observations updates and sqrt(trace Sigma) <= merge_max_sigma, normals within
  // merge_max_normal_angle_deg, the other's centre within merge_plane_sigmas standard deviations of the
  // survivor's plane, footprints touching, and the grown footprint at most merge_max_radius_px wide.
  bool merge_enabled = true;
  std::uint32_t merge_min_observations = 3;
  double merge_max_sigma = 0.05;
  double merge_max_normal_angle_deg = 10.0;
  double merge_plane_sigmas = 3.0;
  double merge_max_radius_px = 8.0;
  // Confirmation by parallax (EXPERIMENTS.md, "Confirmation by parallax"): a new primitive is provisional
  // (primitive_flags::kProvisional) until an accepted match has constrained its depth: its update
  // divided the variance along the seed ray (the direction a wrong spawn match moves the point) by at
  // least 1 + confirm_min_depth_information, i.e. that view's match carried at least this fraction of
  // the prior's information on the depth. For a linear update that is sigma_ray^2 (H d)^T R^-1 (H d) >=
  // confirm_min_depth_information: one prior standard deviation along the ray moves the projection by at
  // least sqrt(that) match standard deviations, so at 1 a depth error beyond 3.5 prior sigmas would have
  // been gated (chi2 2 dof 95 %). A match from a view nearly collinear with the seed ray passes the gate
  // whatever the depth and does not confirm. 0: off (no primitive is flagged).
  double confirm_min_depth_information = 1.0;
  // A provisional primitive still unconfirmed after this many accepted updates is erased (its depth
  // rests on the spawn match alone, and the views that see it cannot tell). 0: kept, flagged.
  std::uint32_t provisional_max_updates = 0;
  // A provisional primitive with at least one accepted update whose match fails or is gated in a view where
  // its prior's seed-ray uncertainty projects to at least sqrt(confirm_min_depth_information) standard
  // deviations of the fixed R (ekf.R_px2, the one that sizes search windows): a view where a wrong depth
  // shows is erased, as a first re-observation that fails is (confirm_spawns). Off: kept, counted as a
  // rejection (kUnconsumed, erase_unsearchable).
  bool erase_provisional_rejected = false;

  // kOk, kNonFiniteInput or kInvalidArgument naming no field (see the README for the ranges).
  Status validate() const;
  // The match floor's covariance in pixels (px^2): match_sigma_floor_rad times each axis's focal length,
  // squared, on the diagonal.
  Eigen::Matrix2d match_floor_px2(const PinholeIntrinsics& intrinsics) const;
};

// Where a primitive's normal came from (ImageFrontEnd::normal_source). The integration test splits the
// normals' errors by it (core/frontend/EXPERIMENTS.md, "Session 25").
enum class NormalSource : std::uint8_t {
  kFacingPrior = 0,  // a new primitive's, or one put in the pool from elsewhere: it faces the creating camera
  kSpawnFit,         // the plane through its neighbours when it was created
  kRefit,            // the plane through its neighbours, refitted after it was tracked
  kPhotometric,      // estimated from its reference patch's appearance in a later image
  kInverseWarp,      // the same estimate, made by an inverse-warp match
  kAdopted,          // given from outside (ImageFrontEnd::adopt_normal)
};

// Whether a plane fit's normal (from `fit`: kSpawnFit or kRefit) replaces a primitive's current one: when
// it claims a smaller tilt variance (a fit from noisy neighbours can know less than the normal already
// has), and, with refit_supersedes_spawn_fit, a refit always replaces the spawn's fit and the facing prior,
// whose claims it does not trust (FrontEndConfig::refit_supersedes_spawn_fit).
bool normal_refit_replaces(NormalSource current, double current_tilt_variance, NormalSource fit,
                           double fit_tilt_variance, bool refit_supersedes_spawn_fit);

// Why tracked observations failed, one count per failed observation (each also counts in its frame's
// UpdateReport::failed_matches). template_masked: the plane map stretches the 7 x 7 template so far that
// fewer than half its pixels sample the stored reference patch, which happens when the view differs much
// from the creating view, and more often when the normal is wrong (EXPERIMENTS.md, "Why tracked matches fail").
struct TrackFailureCounts {
  std::uint64_t edge_on = 0;          // the plane map cannot be formed: the plane is seen edge-on
  std::uint64_t template_masked = 0;  // fewer than half the warped template's pixels inside the reference patch
  std::uint64_t below_threshold = 0;  // MatchOutcome::kBelowThreshold: no NCC peak at ncc_min
  std::uint64_t ambiguous = 0;        // MatchOutcome::kAmbiguous: a second peak within uniqueness_ratio
  std::uint64_t no_room = 0;          // MatchOutcome::kNoRoom: the search left the image
  std::uint64_t no_subpixel = 0;      // MatchOutcome::kNoSubpixel: the photometric fit did not converge
  std::uint64_t too_uncertain = 0;    // found, but its modelled sd above FrontEndConfig::max_match_sigma_rad

  std::uint64_t total() const {
    return edge_on + template_masked + below_threshold + ambiguous + no_room + no_subpixel + too_uncertain;
  }
};

// Cumulative counters over the front end's life.
struct FrontEndStats {
  std::uint64_t frames_accepted = 0;
  std::uint64_t rejected_invalid_image = 0;   // null, zero-size, truncated, or not the intrinsics' size
  std::uint64_t rejected_unusable_image = 0;  // constant, black or saturated
  std::uint64_t rejected_bad_pose = 0;        // NaN/Inf or not a rotation
  std::uint64_t rejected_not_initialized = 0;
  std::uint64_t seeds_tried = 0;              // textured seeds searched along an epipolar line
  std::uint64_t seeds_matched = 0;
  std::uint64_t seeds_rejected_triangulation = 0;
  std::uint64_t seeds_beyond_depth_range = 0;  // best epipolar peak in the guard band (kBeyondDepthRange)
  std::uint64_t seeds_rejected_back_match = 0;  // the left-right check (spawn_back_match_max_px) failed
  std::uint64_t seeds_rejected_no_plane_fit = 0;  // spawn_requires_plane_fit: new primitives erased
  std::uint64_t unconfirmed_erased = 0;       // new primitives whose first re-observation failed
  std::uint64_t gated_erased = 0;             // track loss (FrontEndConfig::max_rejected_in_a_row)
  std::uint64_t unsearchable_erased = 0;      // FrontEndConfig::erase_unsearchable
  std::uint64_t parallax_confirmed = 0;       // provisional primitives confirmed (confirm_min_depth_information)
  std::uint64_t provisional_erased = 0;       // FrontEndConfig::provisional_max_updates, erase_provisional_rejected
  std::uint64_t tracks_predicted = 0;         // tracked primitives predicted in view and not occluded
  std::uint64_t tracks_matched = 0;           // of which matched (the EKF may still gate them: ekf)
  std::uint64_t tracks_inverse_warped = 0;    // of which matched by the inverse warp (inverse_warp_masked)
  std::uint64_t photometric_normals = 0;      // of which matched again with a photometric normal's template
  std::uint64_t photometric_refits_unconverged = 0;  // estimates dropped: their refit did not converge
                                                     // (require_converged_fit)
  TrackFailureCounts track_failures;          // the others, by reason (tracks_predicted = matched + failures)
  EkfStats ekf;
};

// One tracked observation as it went into the EKF update, with the update's outcome (diagnostics, e.g.
// vantage-sim --gate-diagnostics, sim_hal/ground_truth/gate_diagnostics.hpp, which classifies gated
// observations against ground truth).
struct TrackedObservation {
  PrimitiveIndex index = kInvalidPrimitive;
  Primitive prior;                          // the primitive before the update
  Eigen::Vector2d predicted_px = Eigen::Vector2d::Zero();
  Eigen::Vector2d observed_px = Eigen::Vector2d::Zero();
  Eigen::Matrix2d R_px2 = Eigen::Matrix2d::Zero();           // the independent part (warp covariance included)
  Eigen::Matrix2d warp_covariance_px2 = Eigen::Matrix2d::Zero();
  Eigen::Matrix2d common_covariance_px2 = Eigen::Matrix2d::Zero();  // P_c, in the creating image
  Eigen::Matrix<double, 3, 2> common_cross_covariance = Eigen::Matrix<double, 3, 2>::Zero();
  Eigen::Matrix2d B = Eigen::Matrix2d::Identity();           // creating-image shift -> this image
  Viewpoint view;
  Viewpoint creating_view;
  Status outcome = Status::kOk;             // kGatedOutlier: rejected by the Mahalanobis gate (or refused)
  bool inverse_warped = false;              // matched by warping the image (FrontEndConfig::inverse_warp_masked)
  bool refused = false;                     // TrackObserver::refuse said no: no update was made

  // The match's own covariance, px^2: the independent part and the reference patch's common error in this
  // image, R + B P_c B^T (what a match against the truth is to be judged by).
  Eigen::Matrix2d match_covariance_px2() const { return R_px2 + B * common_covariance_px2 * B.transpose(); }
};

// Receives every TrackedObservation (ImageFrontEnd::set_observer). Called inside update(); it must not
// touch the pool.
class TrackObserver {
 public:
  virtual void on_observation(const TrackedObservation& observation) = 0;
  // Asked before each update with the observation as matched (outcome not yet known): true refuses it
  // (no update; reported with refused set and kGatedOutlier, and counted as a gated outlier). A test's
  // ground-truth oracle uses it to measure what the filter would be without the matches it knows to be
  // wrong (core/frontend/EXPERIMENTS.md, "Session 23"). Never set on the robot.
  virtual bool refuse(const TrackedObservation& observation) {
    (void)observation;
    return false;
  }

 protected:
  ~TrackObserver() = default;
};

struct CommonObservationError;  // core/frontend/iterated_update.hpp

class ImageFrontEnd final : public MeasurementSource {
 public:
  ImageFrontEnd() = default;
  ImageFrontEnd(const ImageFrontEnd&) = delete;
  ImageFrontEnd& operator=(const ImageFrontEnd&) = delete;

  // Sets the camera and the configuration and forgets any previous state. kInvalidArgument when the
  // image exceeds kFrontEndMaxWidth x kFrontEndMaxHeight or a field is out of range; on error the front
  // end stays unconfigured.
  Status configure(const PinholeIntrinsics& intrinsics, const FrontEndConfig& config);

  Status initialize(const GrayImageView& first, const Viewpoint& first_view, const GrayImageView& second,
                    const Viewpoint& second_view, PrimitivePoolView& pool, UpdateReport* report) override;
  Status update(const GrayImageView& image, const Viewpoint& view, PrimitivePoolView& pool,
                UpdateReport* report) override;
  const PinholeIntrinsics& intrinsics() const override { return intrinsics_; }

  const FrontEndConfig& config() const { return config_; }
  // Diagnostics: every observation that reaches the EKF update is shown to observer (nullptr: none).
  void set_observer(TrackObserver* observer) { observer_ = observer; }
  const FrontEndStats& stats() const { return stats_; }
  bool configured() const { return configured_; }
  bool initialized() const { return initialized_; }
  // The per-slot tables (normal tilt variance, patch noise, rejection count) describe the primitives this
  // front end created. After primitives were put into the pool by someone else (a model loaded from
  // storage, a test), call this so every slot is treated as such a primitive: facing-camera normal
  // prior, no patch noise, no rejections. initialize() does it too.
  void forget_primitive_tables();
  // Index the next accepted image gets (Primitive::creating_view counts images from 0).
  std::uint32_t next_view_index() const { return next_view_index_; }
  // The pose of an earlier image, if still in the table. kNotFound otherwise.
  Status view_pose(std::uint32_t view_index, Viewpoint* pose) const;
  // The tilt variance (rad^2 per axis) of primitive i's normal: the facing prior, a plane fit's or a
  // photometric estimate's (README, "Normal uncertainty").
  double normal_tilt_variance(PrimitiveIndex i) const;
  // Where primitive i's normal came from (kFacingPrior beyond kFrontEndMaxPrimitives).
  NormalSource normal_source(PrimitiveIndex i) const;
  // The modelled covariance (px^2, in its creating image) of the shift primitive i's reference patch noise
  // gives all its matches (FrontEndConfig::model_template_noise: P_c); zero when not modelled.
  Eigen::Matrix2d template_noise_covariance_px2(PrimitiveIndex i) const;
  // Gives alive primitive i a normal known from elsewhere (a prior model, a range sensor, a simulator's
  // ground truth) with its tilt variance (rad^2 per axis): the warp of its template and the normal's share
  // of R use it from the next update on, and a plane refit or photometric estimate replaces it only when it
  // knows the normal better, as for any normal. kNotFound: i is not alive or beyond kFrontEndMaxPrimitives
  // (whose normals the front end does not track); kNonFiniteInput: a NaN or Inf; kInvalidArgument: a normal
  // not of unit length (within 1e-3) or a variance not above 0. Nothing changes on error.
  Status adopt_normal(PrimitiveIndex i, const Eigen::Vector3d& normal_world, double tilt_variance,
                      PrimitivePoolView& pool);

 private:
  // Checks one frame and its pose; counts the rejection.
  Status check_frame(const GrayImageView& image, const Viewpoint& view);
  void reset_cells();
  std::size_t cell_of(const Eigen::Vector2d& uv_px) const;
  void track(const GrayImageView& image, const Viewpoint& view, PrimitivePoolView& pool, UpdateReport& report);
  void refit_normals(const Viewpoint& view, PrimitivePoolView& pool);
  // Predictions of the next alive primitives from `first` on (up to kDiscBatchSize): their projections and
  // Jacobians in one batch (project_with_jacobian_batch), inside the image and facing the camera, then their
  // occlusion tests in one lane batch (DepthBufferView::is_visible_batch).
  struct PredictionBatch {
    std::array<PrimitiveIndex, kDiscBatchSize> index{};
    std::array<Eigen::Vector2d, kDiscBatchSize> predicted{};
    std::array<Eigen::Matrix<double, 2, 3>, kDiscBatchSize> H{};
    std::array<bool, kDiscBatchSize> in_view{};  // predicted in the image and not occluded
    // Per slot: X's projection Jacobian in its creating view and its status
    // (kNotFound: not in view, or that view's pose is gone), and the plane-induced map from this view to
    // the creating one with its tilt derivatives (plane_affine_from_jacobians_batch), valid where
    // creating_status and plane_status are kOk.
    std::array<Eigen::Matrix<double, 2, 3>, kDiscBatchSize> H_creating{};
    std::array<Status, kDiscBatchSize> creating_status{};
    std::array<Eigen::Matrix2d, kDiscBatchSize> A{};
    std::array<std::array<Eigen::Matrix2d, 2>, kDiscBatchSize> dA{};
    std::array<Status, kDiscBatchSize> plane_status{};
    std::int32_t count = 0;
    std::int32_t next = 0;  // the slot track() takes next
  };
  void predict_batch(PrimitiveIndex first, const Viewpoint& view, bool occlusion, const PrimitivePoolView& pool,
                     PredictionBatch* batch) const;
  // Estimates matched primitive i's normal photometrically (FrontEndConfig::photometric_normal) and
  // matches it again near *observed with the template warped by it; on success adopts the normal and its
  // tilt variance and replaces the template, B, the warp covariance, the match and its fit covariance. False: unchanged.
  // H_creating, H_view: the Jacobians of X's projections into both views.
  bool refine_normal_photometric(PrimitiveIndex i, const GrayImageView& image, const Viewpoint& creating,
                                 const Viewpoint& view, const Eigen::Matrix<double, 2, 3>& H_creating,
                                 const Eigen::Matrix<double, 2, 3>& H_view, PrimitivePoolView& pool,
                                 NccTemplate* tmpl, Eigen::Matrix2d* B,
                                 Eigen::Matrix2d* warp_covariance, Eigen::Vector2d* observed,
                                 Eigen::Matrix2d* fit_covariance);
  // Replaces a match's fit covariance by the one with the residuals' spatial correlation
  // (FrontEndConfig::correlated_fit_covariance) when that can be computed.
  // The EKF update of a tracked primitive with the observer told (observer_ set): the TrackedObservation
  // is built only here, not per primitive when nobody observes.
  // A tracked match on its way to the EKF update: where it was predicted and found, its measurement model
  // (R in ekf, the warp covariance, B, the common error) and what the bookkeeping after the update needs.
  struct MatchedObservation {
    std::size_t centre_cell = 0;
    bool template_noise = false;
    bool have_creating = false;
    bool beyond_search = false;
    bool inverse_warped = false;
    Eigen::Vector2d predicted_px = Eigen::Vector2d::Zero();
    Eigen::Matrix<double, 2, 3> H = Eigen::Matrix<double, 2, 3>::Zero();
    Eigen::Vector2d observed_px = Eigen::Vector2d::Zero();
    EkfConfig ekf;
    Eigen::Matrix2d warp_covariance_px2 = Eigen::Matrix2d::Zero();
    Eigen::Matrix2d B = Eigen::Matrix2d::Identity();
    CommonObservationError common;
  };
  [[gnu::noinline]] Status observed_update(PrimitiveIndex i, Primitive& p, const MatchedObservation& matched,
                                           CommonObservationError* common, const Viewpoint& view,
                                           const Viewpoint& creating);
  void correlate_fit_covariance(const GrayImageView& image, const NccTemplate& tmpl, const Eigen::Vector2d& uv_px,
                                Eigen::Matrix2d* fit_covariance) const;
  // A tracked match's update, held until kUpdateBatchSize are ready (iterated_consider_update_batch), with
  // what the bookkeeping after it needs. Every later primitive with the same centre cell flushes the
  // batch first, so the cells see the same order of claims and erasures as one update at a time.
  struct PendingUpdate {
    PrimitiveIndex index = kInvalidPrimitive;
    std::size_t centre_cell = 0;
    bool template_noise = false;
    bool provisional = false;
    bool have_creating = false;
    bool beyond_search = false;
    Eigen::Matrix3d Sigma_prior = Eigen::Matrix3d::Zero();
    Viewpoint creating;
    CommonObservationError common;
  };
  // Holds primitive i's matched observation for the next batch (updates it at once when an observer
  // watches). Not inlined, nor are the two below: track()'s frame stays under the core's 16 KB limit
  // under ASan.
  [[gnu::noinline]] void hold_update(PrimitiveIndex i, const MatchedObservation& matched, const Viewpoint& creating,
                                     const Viewpoint& view, PrimitivePoolView& pool, UpdateReport& report);
  // Runs the held updates and their bookkeeping in the order they were matched.
  [[gnu::noinline]] void flush_updates(const Viewpoint& view, PrimitivePoolView& pool, UpdateReport& report);
  // The bookkeeping after primitive `pending.index`'s update returned `updated`.
  [[gnu::noinline]] void after_update(const PendingUpdate& pending, Status updated, PrimitivePoolView& pool,
                                      UpdateReport& report);
  // Erases new primitive i whose first re-observation failed or did not happen (FrontEndConfig::
  // confirm_spawns); centre_cell (kNoCell: none) forgets it.
  static constexpr std::size_t kNoCell = ~static_cast<std::size_t>(0);
  void drop_unconfirmed(PrimitiveIndex i, std::size_t centre_cell, PrimitivePoolView& pool);
  // After erasing i: its centre cell (kNoCell: none) no longer names it.
  void forget_cell(PrimitiveIndex i, std::size_t centre_cell);
  // A predicted-in-view observation of primitive i that did not update it (seen edge-on, match failed, or
  // gated): flags kLostTrack, erases an unconfirmed new primitive (confirm_spawns), counts the rejection.
  // beyond_search: the prediction's 3-sigma ellipse was wider than the capped search window.
  void reject_observation(PrimitiveIndex i, std::size_t centre_cell, PrimitivePoolView& pool, UpdateReport& report,
                          bool beyond_search = false);
  // One failed tracked observation into FrontEndStats::track_failures: the template had too few pixels
  // inside the reference patch to search (template_usable false), or the search's outcome.
  void count_track_failure(bool template_usable, MatchOutcome outcome);
  // Whether a found match is too uncertain to use (FrontEndConfig::max_match_sigma_rad): its modelled
  // covariance, R_px2 plus the reference patch's common error through B (zero when no patch noise was
  // recorded) less the deformation error in it (deformation_px2, the model's error), has a mean standard
  // deviation above the limit (or is not a number).
  bool match_too_uncertain(const Eigen::Matrix2d& R_px2, const CommonObservationError& common,
                           const Eigen::Matrix2d& deformation_px2) const;
  // The inverse-warp match of a primitive whose warped template is masked (inverse_warp_masked): true with
  // *observed and *covariance_px2 set, and its normal replaced when the fit knows it better.
  // A maps this image's offsets into the creating image's (the template's warp at the prior normal).
  bool match_by_inverse_warp(PrimitiveIndex i, const GrayImageView& image, const Viewpoint& creating,
                             const Viewpoint& view, const Eigen::Vector2d& predicted, const Eigen::Matrix2d& A,
                             PrimitivePoolView& pool, Eigen::Vector2d* observed, Eigen::Matrix2d* covariance_px2);
  // Counts one failed or gated observation of primitive i; flags it kUnconsumed at
  // unconsumed_after_rejections, erases it at max_rejected_in_a_row.
  void count_rejection(PrimitiveIndex i, std::size_t centre_cell, PrimitivePoolView& pool, UpdateReport& report,
                       bool beyond_search);
  // After an accepted update of provisional primitive i (prior covariance Sigma_prior): clears
  // kProvisional when the update constrained its depth along the seed ray (from creating, or Sigma_prior's
  // major axis when null), erases it at provisional_max_updates otherwise (FrontEndConfig).
  void judge_provisional(PrimitiveIndex i, const Eigen::Matrix3d& Sigma_prior, const Viewpoint* creating,
                         std::size_t centre_cell, PrimitivePoolView& pool, UpdateReport& report);
  // Erases tracked primitive i, counted in *erased_count (a FrontEndStats field) and UpdateReport::gated_erased,
  // and forgets its rejections and its cell (track loss, unsearchable, provisional).
  void erase_tracked(PrimitiveIndex i, std::size_t centre_cell, PrimitivePoolView& pool, UpdateReport& report,
                     std::uint64_t* erased_count);
  // Whether provisional primitive p's seed-ray uncertainty projects into view to at least
  // sqrt(confirm_min_depth_information) standard deviations of ekf.R_px2 (erase_provisional_rejected).
  bool depth_would_show(const Primitive& p, const Viewpoint& view) const;
  void merge_neighbours(const Viewpoint& view, PrimitivePoolView& pool, UpdateReport& report);
  // Positions of the alive primitives in the 8 cells around (cx, cy), for a plane fit; with a finite
  // max_sigma only those whose sigma bound is below it. Returns how many were written to *out.
  // Their covariances go to *sigmas when it is not null.
  std::size_t neighbour_positions(std::int32_t cx, std::int32_t cy, const PrimitivePoolView& pool, double max_sigma,
                                  std::array<Eigen::Vector3d, kFrontEndMaxNormalFitNeighbours>* out,
                                  std::array<Eigen::Matrix3d, kFrontEndMaxNormalFitNeighbours>* sigmas = nullptr) const;
  // Refits primitive i's normal from the neighbours of cell (cx, cy) (spacing: the cells' spacing at its
  // depth, scene units; max_sigma: the neighbours' largest sigma_bound); keeps the fit when
  // normal_refit_replaces says so. The camera orients the normal; along_rays picks
  // fit_plane_normal_along_rays (the neighbours' errors along that camera's rays), else fit_plane_normal;
  // source says which fit it is (kSpawnFit or kRefit).
  void fit_normal(PrimitiveIndex i, std::int32_t cx, std::int32_t cy, double spacing, double max_sigma,
                  const Eigen::Vector3d& camera_world, bool along_rays, NormalSource source, PrimitivePoolView& pool);
  // P_c of a new primitive whose two-view match has fit covariance fit_covariance_px2: the template's half
  // of it. False when the patch noise is not modelled (FrontEndConfig::model_template_noise, adaptive_R).
  bool spawn_patch_noise_px2(const Eigen::Matrix2d& fit_covariance_px2, Eigen::Matrix2d* P_c) const;
  // The template noise of a new primitive i triangulated from its seed and a match in other_view with
  // covariance R_other_px2 (of which the fit's fit_covariance_px2).
  void remember_template_noise(PrimitiveIndex i, const Primitive& p, const Viewpoint& other_view,
                               std::uint32_t other_index, const Eigen::Matrix2d& R_other_px2,
                               const Eigen::Matrix2d& fit_covariance_px2);
  // Primitive i's common error for a match in `view` (view index next_view_index_): the patch noise and,
  // with view_correlated_error_scale or deformation_error_scale, the view-correlated error decayed since its
  // last update (deformation_px2: this match's deformation error, deformation_error_px2).
  void common_error_for_match(PrimitiveIndex i, const Primitive& p, const Viewpoint& view,
                              const Eigen::Matrix2d& deformation_px2, CommonObservationError* common) const;
  // FrontEndConfig::deformation_error_scale's covariance for a match whose reference patch the warp B
  // (reference patch -> this image) maps (px^2, in the reference patch's frame; zero when off).
  Eigen::Matrix2d deformation_error_px2(const Eigen::Matrix2d& B) const;
  void set_normal_tilt_variance(PrimitiveIndex i, double variance, NormalSource source);
  // Seeds in uncovered cells of `reference`, matched along epipolar lines in `other`, become primitives.
  void spawn(const GrayImageView& reference, const Viewpoint& reference_view, std::uint32_t reference_index,
             const GrayImageView& other, const Viewpoint& other_view, std::uint32_t other_index,
             PrimitivePoolView& pool, UpdateReport& report);
  // The left-right check of a spawn match (FrontEndConfig::spawn_back_match_max_px): true when the patch
  // at matched_px in `other` matches back along forward's epipolar line, read the other way, within the
  // bound of the seed, or when that search has no room; searches in spawn()'s epipolar scratch. Not
  // inlined: its template stays off spawn()'s frame (the core's 16 KB frame limit under ASan).
  [[gnu::noinline]] bool matches_back(const GrayImageView& reference, const GrayImageView& other,
                                     const EpipolarQuery& forward, const Eigen::Vector2d& matched_px,
                                     const MatchConfig& match, Span<float> ncc_scratch,
                                     Span<std::int32_t> xy_scratch);
  // Keeps `image` (the frame as the matcher read it) as the previous frame; no copy when it already is
  // previous_image_.
  void remember(const GrayImageView& image, const Viewpoint& view);
  // The frame the matcher reads: `image` itself, or its low-pass written into *into (presmooth).
  GrayImageView working_frame(const GrayImageView& image,
                              GrayImageBuffer<kFrontEndMaxWidth, kFrontEndMaxHeight>* into) const;
  // R of one match from its fit covariance (see FrontEndConfig::adaptive_R).
  Eigen::Matrix2d measurement_R(const Eigen::Matrix2d& fit_covariance_px2) const;

  PinholeIntrinsics intrinsics_;
  FrontEndConfig config_;
  // config_.match_floor_px2(intrinsics_), formed once at configure(): it enters every match's R.
  Eigen::Matrix2d match_floor_px2_ = Eigen::Matrix2d::Zero();
  // What FrontEndConfig::match_floor_tilt_power adds to a tracked match's floor (px^2; zero when off).
  Eigen::Matrix2d tilt_floor_excess_px2(const Primitive& p, const Viewpoint& view, const Viewpoint* creating) const;
  // (config_.max_match_sigma_rad times the mean focal length)^2, formed once at configure(); 0: no limit.
  double max_match_variance_px2_ = 0.0;
  FrontEndStats stats_;
  bool configured_ = false;
  bool initialized_ = false;
  TrackObserver* observer_ = nullptr;
  Viewpoint tracking_view_;  // the view track() is matching (reject_observation's parallax test)
  std::uint32_t next_view_index_ = 0;

  GrayImageBuffer<kFrontEndMaxWidth, kFrontEndMaxHeight> previous_image_;
  GrayImageBuffer<kFrontEndMaxWidth, kFrontEndMaxHeight> smoothed_image_;  // this frame's low-pass (presmooth)
  Viewpoint previous_view_;
  std::array<Viewpoint, kFrontEndMaxViews> view_poses_{};  // view i at i % kFrontEndMaxViews

  // Per seed cell of the current image: the nearest primitive whose projection falls in it, its camera
  // depth, whether any primitive's footprint covers it, and whether its primitive was updated now.
  std::int32_t cells_x_ = 0;
  std::int32_t cells_y_ = 0;
  std::array<PrimitiveIndex, kFrontEndMaxCells> cell_primitive_{};
  std::array<float, kFrontEndMaxCells> cell_depth_{};
  std::array<std::uint8_t, kFrontEndMaxCells> cell_covered_{};
  std::array<std::uint8_t, kFrontEndMaxCells> cell_state_{};  // kCellUpdated | kCellSpawned

  // Tilt variance (rad^2 per axis) of each primitive's normal, by pool index.
  std::array<float, kFrontEndMaxPrimitives> normal_tilt_variance_{};
  std::array<NormalSource, kFrontEndMaxPrimitives> normal_source_{};
  // Consecutive failed or gated observations of each primitive (FrontEndConfig::max_rejected_in_a_row).
  std::array<std::uint8_t, kFrontEndMaxPrimitives> rejected_in_a_row_{};
  // The reference patch's noise per primitive (FrontEndConfig::model_template_noise): its covariance in
  // the creating image and its cross-covariance with the position error. Zero: not modelled.
  // With view_correlated_error_scale, also the view-correlated error's cross-covariance at the view of
  // the last accepted update (or the spawn's other view), and that view's index.
  struct TemplateNoise {
    Eigen::Matrix<float, 3, 2, Eigen::DontAlign> cross_covariance;
    Eigen::Matrix<float, 2, 2, Eigen::DontAlign> covariance_px2;
    Eigen::Matrix<float, 3, 2, Eigen::DontAlign> correlated_cross_covariance;
    std::uint32_t correlated_view;
    // The trace of s's covariance at that update (px^2): a varying variance scales the carried
    // cross-covariance by the ratio of standard deviations (deformation_error_scale).
    float correlated_trace;
  };
  std::array<TemplateNoise, kFrontEndMaxPrimitives> template_noise_;

  DepthBuffer<> depth_buffer_;
  std::array<PendingUpdate, kUpdateBatchSize> pending_updates_;
  std::array<ConsiderUpdateRequest, kUpdateBatchSize> update_requests_;
  int pending_count_ = 0;
  std::array<float, window_scratch_size(kFrontEndMaxHalfWindow)> window_scratch_{};
  std::array<float, kFrontEndMaxEpipolarSamples> epipolar_ncc_{};
  std::array<std::int32_t, 2 * kFrontEndMaxEpipolarSamples> epipolar_xy_{};
};

}  // namespace vantage
