// Thin, non-template shim over octomap::OcTree for the Rust bindings (see src/bridge.rs).
//
// Every function that can fail runs its body through `guarded()` (octomap_shim.cc): library
// output written to stderr/std::cerr meanwhile is captured per thread and handed back in
// `log`, and any C++ exception is caught and rethrown as std::runtime_error for cxx.
#pragma once

#include <cstdint>
#include <istream>
#include <memory>

#include <octomap/OcTree.h>

#include "rust/cxx.h"

namespace froctomap_shim {

struct LeafRecord;
struct OccupancyParameters;

// An OcTree with access to the protected members the shim needs (the root pointer, the
// node count and the header reader), so trees can be built leaf by leaf and read with the
// library's own header parser.
class ShimTree : public octomap::OcTree {
 public:
  explicit ShimTree(double resolution);
  ShimTree(const ShimTree& other) = default;

  // AbstractOcTree::read() for this class: first line, readHeader(), readData().
  void read_full_stream(std::istream& stream);
  // Creates the nodes on the path to one leaf and sets its value. Leaves must come in
  // strictly increasing, non-overlapping Morton order.
  void insert_leaf(const LeafRecord& leaf);
  void export_leaves_into(rust::Vec<LeafRecord>& out) const;

 private:
  void export_node(const octomap::OcTreeNode* node, unsigned depth, uint16_t x, uint16_t y,
                   uint16_t z, rust::Vec<LeafRecord>& out) const;
  uint64_t next_free_code_ = 0;
  bool has_leaves_ = false;
};

std::unique_ptr<ShimTree> new_tree(double resolution, rust::Vec<uint8_t>& log);
std::unique_ptr<ShimTree> clone_tree(const ShimTree& tree, rust::Vec<uint8_t>& log);
std::unique_ptr<ShimTree> read_binary(rust::Slice<const uint8_t> data, rust::Vec<uint8_t>& log,
                                      bool& complete);
std::unique_ptr<ShimTree> read_full(rust::Slice<const uint8_t> data, rust::Vec<uint8_t>& log);
rust::Vec<uint8_t> write_binary(ShimTree& tree, rust::Vec<uint8_t>& log);
rust::Vec<uint8_t> write_binary_unchanged(const ShimTree& tree, rust::Vec<uint8_t>& log);
rust::Vec<uint8_t> write_full(const ShimTree& tree, rust::Vec<uint8_t>& log);

double resolution(const ShimTree& tree);
uint32_t tree_depth(const ShimTree& tree);
uint64_t node_count(const ShimTree& tree);
uint64_t leaf_count(const ShimTree& tree);
OccupancyParameters occupancy_parameters(const ShimTree& tree);
void set_occupancy_parameters(ShimTree& tree, const OccupancyParameters& parameters,
                              rust::Vec<uint8_t>& log);

rust::Vec<LeafRecord> export_leaves(const ShimTree& tree, rust::Vec<uint8_t>& log);
std::unique_ptr<ShimTree> build_tree(double resolution, rust::Slice<const LeafRecord> leaves,
                                     rust::Vec<uint8_t>& log);
bool search(const ShimTree& tree, uint16_t x, uint16_t y, uint16_t z, float& log_odds);

void prune(ShimTree& tree, rust::Vec<uint8_t>& log);
void expand(ShimTree& tree, rust::Vec<uint8_t>& log);
void to_max_likelihood(ShimTree& tree, rust::Vec<uint8_t>& log);
void update_inner_occupancy(ShimTree& tree, rust::Vec<uint8_t>& log);

}  // namespace froctomap_shim
