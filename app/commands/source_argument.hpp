#pragma once

#include <functional>
#include <memory>
#include <string>

#include "nirslam/capture/camera_controls.hpp"

#include "nirslam/worker/worker.hpp"

namespace nirslam::app {

// What a SOURCE argument on the command line names: a simulated scene ("sim:tunnel", "sim:room",
// "sim:parking", "sim:outdoor"; "sim" is the tunnel; "sim:room@20W" sets the lamp's power), "demo" for the light-weight synthetic wall
// (fast, for tests), or a dataset path (TUM monoVO, EuRoC, image folder). The path is checked now, so a typo is reported
// before any window opens; the source itself is opened on the worker thread.
SourceFactory source_factory_from_argument(const std::string& argument);

// Whether the argument names one of the built-in sequences rather than a dataset.
bool is_built_in_sequence(const std::string& argument);

// Called on the worker thread with the camera controls of every source a factory from
// source_factory_from_argument opens (a V4L2 camera's, the simulator's; nullptr when a source
// without them opens), so the GUI's camera panel can drive the camera the worker streams from.
using CameraControlsSink = std::function<void(std::shared_ptr<CameraControls>)>;
SourceFactory source_factory_from_argument(const std::string& argument, CameraControlsSink on_open);

// The sequence nirslam shows when started without one.
inline constexpr const char* kDefaultSource = "sim:tunnel";

inline constexpr const char* kSourceArgumentHelp =
    "'sim:tunnel' (simulated; also sim:room, sim:parking, sim:outdoor; '@20W' sets the lamp power), 'demo' (synthetic wall), a "
    "dataset folder (TUM monoVO, EuRoC mav0/cam0, a folder of images) a recorded session folder ('session:DIR') or a camera: "
    "'v4l2:/dev/video0?format=Y16&size=640x480&fps=30' ('v4l2-emulated:/dev/video0' for the emulated one)";

}  // namespace nirslam::app
