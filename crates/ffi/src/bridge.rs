//! The raw `cxx` bridge to `shim/octomap_shim.{h,cc}`. Everything here is wrapped by the safe
//! API in `lib.rs`; the shim catches every C++ exception and rethrows it as a
//! `std::runtime_error`, which `cxx` turns into an `Err` for functions returning `Result`.

#[cxx::bridge(namespace = "froctomap_shim")]
pub(crate) mod ffi {
    /// One leaf of a tree, exported or imported in bulk.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct LeafRecord {
        /// Minimum-corner key along x (not upstream's centre key).
        pub x: u16,
        /// Minimum-corner key along y.
        pub y: u16,
        /// Minimum-corner key along z.
        pub z: u16,
        /// Depth of the leaf, 0 (root) ..= 16 (voxel).
        pub depth: u8,
        /// Occupancy log-odds.
        pub log_odds: f32,
    }

    /// The occupancy parameters of a tree, as probabilities.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct OccupancyParameters {
        /// A node is occupied at or above this probability.
        pub occupancy_threshold: f64,
        /// Sensor model: probability of a hit.
        pub prob_hit: f64,
        /// Sensor model: probability of a miss.
        pub prob_miss: f64,
        /// Lower clamping bound.
        pub clamping_min: f64,
        /// Upper clamping bound.
        pub clamping_max: f64,
    }

    unsafe extern "C++" {
        include!("froctomap-octomap-ffi/shim/octomap_shim.h");

        type ShimTree;

        fn new_tree(resolution: f64, log: &mut Vec<u8>) -> Result<UniquePtr<ShimTree>>;
        fn clone_tree(tree: &ShimTree, log: &mut Vec<u8>) -> Result<UniquePtr<ShimTree>>;
        fn read_binary(
            data: &[u8],
            log: &mut Vec<u8>,
            complete: &mut bool,
        ) -> Result<UniquePtr<ShimTree>>;
        fn read_full(data: &[u8], log: &mut Vec<u8>) -> Result<UniquePtr<ShimTree>>;
        fn write_binary(tree: Pin<&mut ShimTree>, log: &mut Vec<u8>) -> Result<Vec<u8>>;
        fn write_binary_unchanged(tree: &ShimTree, log: &mut Vec<u8>) -> Result<Vec<u8>>;
        fn write_full(tree: &ShimTree, log: &mut Vec<u8>) -> Result<Vec<u8>>;

        fn resolution(tree: &ShimTree) -> f64;
        fn tree_depth(tree: &ShimTree) -> u32;
        fn node_count(tree: &ShimTree) -> u64;
        fn leaf_count(tree: &ShimTree) -> u64;
        fn occupancy_parameters(tree: &ShimTree) -> OccupancyParameters;
        fn set_occupancy_parameters(
            tree: Pin<&mut ShimTree>,
            parameters: &OccupancyParameters,
            log: &mut Vec<u8>,
        ) -> Result<()>;

        fn export_leaves(tree: &ShimTree, log: &mut Vec<u8>) -> Result<Vec<LeafRecord>>;
        fn build_tree(
            resolution: f64,
            leaves: &[LeafRecord],
            log: &mut Vec<u8>,
        ) -> Result<UniquePtr<ShimTree>>;
        fn search(tree: &ShimTree, x: u16, y: u16, z: u16, log_odds: &mut f32) -> bool;

        fn prune(tree: Pin<&mut ShimTree>, log: &mut Vec<u8>) -> Result<()>;
        fn expand(tree: Pin<&mut ShimTree>, log: &mut Vec<u8>) -> Result<()>;
        fn to_max_likelihood(tree: Pin<&mut ShimTree>, log: &mut Vec<u8>) -> Result<()>;
        fn update_inner_occupancy(tree: Pin<&mut ShimTree>, log: &mut Vec<u8>) -> Result<()>;
    }
}

// SAFETY: a ShimTree is a heap-allocated octomap::OcTree owned through a UniquePtr; it holds
// no thread-local state and no references to other objects, so it may move between threads.
// It is not Sync: some const OcTree queries update lazily cached values.
unsafe impl Send for ffi::ShimTree {}
