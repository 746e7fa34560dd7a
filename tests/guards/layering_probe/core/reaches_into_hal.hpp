#pragma once
// Probe for guard_layering_rejects_probe: core reaching into a driver must be rejected.
#include "hal/v4l2/v4l2_camera.hpp"
