//! The ROS names froctomap publishes and serves under, in one place: the MCAP export and
//! the ROS 2 node (crate `froctomap-ros2-node`) both take them from here, so a recording
//! exported from a file and the live node show the same topics.

/// The maps (`octomap_msgs/msg/Octomap`), as `octomap_server` names its binary map topic:
/// what the node subscribes by default and what the MCAP export writes the maps on.
pub const OCTOMAP_TOPIC: &str = "/octomap_binary";
/// The map the model predicts (`octomap_msgs/msg/Octomap`, latched), published by the node.
pub const PREDICTED_TOPIC: &str = "/froctomap/predicted";
/// The predicted map's occupied cells for rviz2 (`visualization_msgs/msg/MarkerArray`, one
/// `CUBE_LIST` per depth as `octomap_server`'s `occupied_cells_vis_array`), coloured by
/// their probability: see [`encode_occupied_marker_array_cdr`](crate::encode_occupied_marker_array_cdr).
pub const DYNAMIC_TOPIC: &str = "/froctomap/dynamic";
/// The exported maps' occupied cells for rviz2 (`visualization_msgs/msg/MarkerArray`, one
/// `CUBE_LIST` per depth, as `octomap_server`'s `occupied_cells_vis_array`).
pub const OCCUPIED_CELLS_TOPIC: &str = "/froctomap/occupied_cells_vis_array";
/// The exported maps' occupied voxels (`foxglove.PointCloud`, JSON; profile `foxglove`).
pub const POINT_CLOUD_TOPIC: &str = "/froctomap/occupied_voxels";
/// The exported maps' occupied cells as Foxglove cubes sized by the cell
/// (`foxglove.SceneUpdate`, JSON; profile `foxglove`).
pub const SCENE_TOPIC: &str = "/froctomap/occupied_cubes";
/// The exported maps' occupied voxels as `sensor_msgs/msg/PointCloud2`.
pub const POINT_CLOUD2_TOPIC: &str = "/froctomap/occupied_voxels_pc2";
/// The simulated time (`rosgraph_msgs/msg/Clock`) a node with `use_sim_time` follows.
pub const CLOCK_TOPIC: &str = "/clock";
/// The service giving the map at a time (`froctomap_msgs/srv/GetOctomapAt`).
pub const GET_OCTOMAP_AT_SERVICE: &str = "/froctomap/get_octomap_at";
/// The service giving occupancy probabilities at points (`froctomap_msgs/srv/ProbabilityAt`).
pub const PROBABILITY_AT_SERVICE: &str = "/froctomap/probability_at";
/// The frame the MCAP export's messages are in.
pub const FRAME_ID: &str = "map";
