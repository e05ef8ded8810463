//! The ROS 1 bag reader on arbitrary bytes (bags carry no checksums: every mutated length
//! reaches the reader as it is).
#![no_main]

mod recording;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    recording::read_recording(&froctomap_ros::ROSBAG, data);
});
