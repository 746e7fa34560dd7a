#pragma once
// The sensing policies the executive can run: ours and the baselines of the comparison (issue 6).
//   nbv       NBV + SplitPath + PredictModel; replan on U < eta, blocked path, or path end (Fig. 3).
//   reactive  a new NBV after every image (the "reactive NBV approach" of section VI), no path goals:
//             moves one SplitPath waypoint toward the current NBV, senses, recomputes.
//   direct    moves to the NBV along PathQry with no intermediate sensing, senses once there, replans.
//   orbit     a circle of radius orbit_radius_m around the grid centre, sensing at every cell on it,
//             lap after lap, until the goals or the image budget.
//   random    random free cells reachable from the current one, sensing at each.
#include <cstdint>

namespace vantage {

enum class PlannerPolicy : std::uint8_t { kNbv = 0, kReactive, kDirect, kOrbit, kRandom };

inline constexpr PlannerPolicy kAllPlannerPolicies[] = {PlannerPolicy::kNbv, PlannerPolicy::kReactive,
                                                        PlannerPolicy::kDirect, PlannerPolicy::kOrbit,
                                                        PlannerPolicy::kRandom};

const char* to_string(PlannerPolicy policy);
// Parses "nbv", "reactive", "direct", "orbit", "random"; false (policy untouched) otherwise.
bool parse_planner_policy(const char* name, PlannerPolicy* policy);

// True for the policies that read the criterion's cost (they need the grid evaluated before planning).
inline bool policy_uses_criterion(PlannerPolicy policy) {
  return policy == PlannerPolicy::kNbv || policy == PlannerPolicy::kReactive || policy == PlannerPolicy::kDirect;
}

}  // namespace vantage
