#pragma once
// The eight common-dialect messages vantage speaks, with their wire layout. Field order on the wire is
// the MAVLink rule: base fields sorted by type size (largest first, stable), extension fields appended
// in declaration order. CRC_EXTRA values are those mavgen derives from common.xml (checked against the
// generated tables of two independent implementations; see README.md).
#include <array>
#include <cstddef>
#include <cstdint>

namespace vantage::hal::mavlink {

enum MessageId : std::uint32_t {
  kHeartbeatId = 0,
  kAttitudeId = 30,
  kLocalPositionNedId = 32,
  kCommandLongId = 76,
  kCommandAckId = 77,
  kSetPositionTargetLocalNedId = 84,
  kPositionTargetLocalNedId = 85,
  kOdometryId = 331,
};

struct MessageSpec {
  std::uint32_t id;
  std::uint8_t crc_extra;
  std::uint8_t base_length;  // payload bytes without extensions (MAVLink 1 length)
  std::uint8_t max_length;   // payload bytes with extensions
  const char* name;
};

// nullptr for a message id this codec does not know.
const MessageSpec* find_message_spec(std::uint32_t id);

// Common enum values used by the driver and its tests.
constexpr std::uint8_t kMavFrameLocalNed = 1;
constexpr std::uint8_t kMavFrameBodyFrd = 12;
constexpr std::uint8_t kMavTypeOnboardController = 18;
constexpr std::uint8_t kMavAutopilotInvalid = 8;
constexpr std::uint8_t kMavStateActive = 4;
constexpr std::uint16_t kMavCmdSetMessageInterval = 511;
constexpr std::uint8_t kMavResultAccepted = 0;

// SET_POSITION_TARGET_LOCAL_NED type_mask bits: a set bit means "ignore this field".
constexpr std::uint16_t kIgnorePosition = 0x0007;
constexpr std::uint16_t kIgnoreVelocity = 0x0038;
constexpr std::uint16_t kIgnoreAcceleration = 0x01C0;
constexpr std::uint16_t kForceSetpoint = 0x0200;
constexpr std::uint16_t kIgnoreYaw = 0x0400;
constexpr std::uint16_t kIgnoreYawRate = 0x0800;

struct Heartbeat {
  static constexpr std::uint32_t kId = kHeartbeatId;
  std::uint32_t custom_mode = 0;
  std::uint8_t type = 0;
  std::uint8_t autopilot = 0;
  std::uint8_t base_mode = 0;
  std::uint8_t system_status = 0;
  std::uint8_t mavlink_version = 3;
};

struct SetPositionTargetLocalNed {
  static constexpr std::uint32_t kId = kSetPositionTargetLocalNedId;
  std::uint32_t time_boot_ms = 0;
  float x = 0, y = 0, z = 0;        // m, NED
  float vx = 0, vy = 0, vz = 0;     // m/s
  float afx = 0, afy = 0, afz = 0;  // m/s^2
  float yaw = 0;                    // rad, from north toward east
  float yaw_rate = 0;               // rad/s
  std::uint16_t type_mask = 0;
  std::uint8_t target_system = 0;
  std::uint8_t target_component = 0;
  std::uint8_t coordinate_frame = kMavFrameLocalNed;
};

struct PositionTargetLocalNed {
  static constexpr std::uint32_t kId = kPositionTargetLocalNedId;
  std::uint32_t time_boot_ms = 0;
  float x = 0, y = 0, z = 0;
  float vx = 0, vy = 0, vz = 0;
  float afx = 0, afy = 0, afz = 0;
  float yaw = 0;
  float yaw_rate = 0;
  std::uint16_t type_mask = 0;
  std::uint8_t coordinate_frame = kMavFrameLocalNed;
};

struct LocalPositionNed {
  static constexpr std::uint32_t kId = kLocalPositionNedId;
  std::uint32_t time_boot_ms = 0;
  float x = 0, y = 0, z = 0;     // m, NED
  float vx = 0, vy = 0, vz = 0;  // m/s
};

struct Attitude {
  static constexpr std::uint32_t kId = kAttitudeId;
  std::uint32_t time_boot_ms = 0;
  float roll = 0, pitch = 0, yaw = 0;                 // rad
  float rollspeed = 0, pitchspeed = 0, yawspeed = 0;  // rad/s
};

struct Odometry {
  static constexpr std::uint32_t kId = kOdometryId;
  std::uint64_t time_usec = 0;
  float x = 0, y = 0, z = 0;
  std::array<float, 4> q{1.0f, 0.0f, 0.0f, 0.0f};  // w, x, y, z: child frame to frame_id
  float vx = 0, vy = 0, vz = 0;
  float rollspeed = 0, pitchspeed = 0, yawspeed = 0;
  std::array<float, 21> pose_covariance{};
  std::array<float, 21> velocity_covariance{};
  std::uint8_t frame_id = kMavFrameLocalNed;
  std::uint8_t child_frame_id = kMavFrameBodyFrd;
  std::uint8_t reset_counter = 0;   // extension
  std::uint8_t estimator_type = 0;  // extension
  std::int8_t quality = 0;          // extension
};

struct CommandLong {
  static constexpr std::uint32_t kId = kCommandLongId;
  std::array<float, 7> param{};
  std::uint16_t command = 0;
  std::uint8_t target_system = 0;
  std::uint8_t target_component = 0;
  std::uint8_t confirmation = 0;
};

struct CommandAck {
  static constexpr std::uint32_t kId = kCommandAckId;
  std::uint16_t command = 0;
  std::uint8_t result = 0;
  std::uint8_t progress = 0;        // extension
  std::int32_t result_param2 = 0;   // extension
  std::uint8_t target_system = 0;   // extension
  std::uint8_t target_component = 0;  // extension
};

// encode() writes the full (untruncated) payload into out, which holds at least the message's
// max_length bytes, and returns that length. decode() reads a payload that the parser zero-extended to
// 255 bytes (MAVLink 2 truncates trailing zeros on the wire).
std::size_t encode(const Heartbeat& m, std::uint8_t* out);
std::size_t encode(const SetPositionTargetLocalNed& m, std::uint8_t* out);
std::size_t encode(const PositionTargetLocalNed& m, std::uint8_t* out);
std::size_t encode(const LocalPositionNed& m, std::uint8_t* out);
std::size_t encode(const Attitude& m, std::uint8_t* out);
std::size_t encode(const Odometry& m, std::uint8_t* out);
std::size_t encode(const CommandLong& m, std::uint8_t* out);
std::size_t encode(const CommandAck& m, std::uint8_t* out);

void decode(const std::uint8_t* payload, Heartbeat* m);
void decode(const std::uint8_t* payload, SetPositionTargetLocalNed* m);
void decode(const std::uint8_t* payload, PositionTargetLocalNed* m);
void decode(const std::uint8_t* payload, LocalPositionNed* m);
void decode(const std::uint8_t* payload, Attitude* m);
void decode(const std::uint8_t* payload, Odometry* m);
void decode(const std::uint8_t* payload, CommandLong* m);
void decode(const std::uint8_t* payload, CommandAck* m);

}  // namespace vantage::hal::mavlink
