#pragma once

// Layout constants shared by the scene builders, the ground textures and the trajectories
// (private to core/sim). Metres, world frame z up.

namespace nirslam::sim::layout {

// Room: the inside of [-4, 4] x [-3, 3] x [0, 2.8]; the camera loops on an ellipse round the table.
inline constexpr float kRoomHalfX = 4.0f, kRoomHalfY = 3.0f, kRoomHeight = 2.8f;
inline constexpr double kRoomLoopA = 2.3, kRoomLoopB = 1.5;

// Outdoor: a building block [-15, 15] x [-7, 7]; pavement to 1.5 m from it, then a 7 m road, an
// outer pavement, and the outer buildings from 10.5 m. The camera loops round the block.
inline constexpr float kBlockHalfX = 15.0f, kBlockHalfY = 7.0f;
inline constexpr float kInnerPavement = 1.5f, kRoadOuter = 8.5f, kOuterFacade = 10.5f;
inline constexpr float kLaneCentre = 5.0f;
inline constexpr double kStreetLoopOffset = 3.5;

// Parking: the inside of [-32, 32] x [-18, 18] x [0, 2.7]; pillar rows at y = 0 and y = +-14,
// cars between, aisles centred at y = +-7. The camera loops round the central row.
inline constexpr float kParkHalfX = 32.0f, kParkHalfY = 18.0f, kParkHeight = 2.7f;
inline constexpr float kPillarSpacing = 8.0f, kPillarHalf = 0.3f, kOuterRowY = 14.0f;
inline constexpr float kCarRowInner = 0.5f, kCarRowOuter = 5.1f;  // |y| of central-row cars
inline constexpr float kOuterCarsFrom = 9.0f, kOuterCarsTo = 13.6f;
inline constexpr float kBayWidth = 8.0f / 3.0f;
inline constexpr float kCarsHalfX = 20.0f;  // cars stand in |x| < 20
inline constexpr double kAisleY = 7.0, kParkLoopHalfX = 22.0;

// Tunnel: a tube of radius 1.8 about the x axis at (y, z) = (0, 1.8), x in [-40, 40], walkway
// floor at z = 0.35. The camera walks up one side and back the other.
inline constexpr float kTubeRadius = 1.8f, kTubeAxisZ = 1.8f, kTubeHalfLength = 40.0f;
inline constexpr float kWalkwayZ = 0.35f;
inline constexpr double kTunnelLoopHalfX = 30.0, kTunnelLoopHalfY = 0.55;

}  // namespace nirslam::sim::layout
