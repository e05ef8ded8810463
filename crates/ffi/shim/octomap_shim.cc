#include "froctomap-octomap-ffi/shim/octomap_shim.h"
#include "froctomap-octomap-ffi/src/bridge.rs.h"

#include <cstdio>
#include <iostream>
#include <mutex>
#include <new>
#include <sstream>
#include <stdexcept>
#include <string>

namespace froctomap_shim {
namespace {

constexpr unsigned kTreeDepth = 16;

// Text the library printed on this thread during the current shim call.
thread_local std::string captured_output;

// Replaces std::cerr's buffer: appends to the calling thread's capture.
class CaptureBuffer : public std::streambuf {
 protected:
  int_type overflow(int_type c) override {
    if (!traits_type::eq_int_type(c, traits_type::eof())) {
      captured_output.push_back(traits_type::to_char_type(c));
    }
    return traits_type::not_eof(c);
  }
  std::streamsize xsputn(const char* s, std::streamsize n) override {
    captured_output.append(s, static_cast<size_t>(n));
    return n;
  }
};

ssize_t write_to_capture(void*, const char* buffer, size_t size) {
  captured_output.append(buffer, size);
  return static_cast<ssize_t>(size);
}

// Debian's liboctomap is built without NDEBUG and prints progress lines with both
// fprintf(stderr) and std::cerr. Both are redirected once per process into per-thread
// buffers, so the chatter never reaches the terminal and error text can be reported with the
// failing call. Rust's own stderr writes go to fd 2 directly and are unaffected.
void install_capture() {
  static std::once_flag once;
  std::call_once(once, [] {
    static CaptureBuffer buffer;
    std::cerr.rdbuf(&buffer);
    cookie_io_functions_t functions = {nullptr, write_to_capture, nullptr, nullptr};
    if (FILE* capture = fopencookie(nullptr, "w", functions)) {
      setvbuf(capture, nullptr, _IONBF, 0);
      stderr = capture;  // glibc documents stderr as an assignable variable
    }
  });
}

void move_capture_into(rust::Vec<uint8_t>& log) {
  log.reserve(log.size() + captured_output.size());
  for (char c : captured_output) {
    log.push_back(static_cast<uint8_t>(c));
  }
  captured_output.clear();
}

// Runs `body`, collecting library output into `log` and turning every exception into a
// std::runtime_error (the only kind cxx converts to a Rust error instead of aborting).
template <typename Body>
auto guarded(rust::Vec<uint8_t>& log, Body&& body) -> decltype(body()) {
  install_capture();
  captured_output.clear();
  try {
    auto result = body();
    move_capture_into(log);
    return result;
  } catch (const std::bad_alloc&) {
    move_capture_into(log);
    throw std::runtime_error("out of memory inside the OctoMap library");
  } catch (const std::exception& error) {
    move_capture_into(log);
    throw std::runtime_error(error.what());
  } catch (...) {
    move_capture_into(log);
    throw std::runtime_error("the OctoMap library threw a non-standard exception");
  }
}

template <typename Body>
void guarded_void(rust::Vec<uint8_t>& log, Body&& body) {
  guarded(log, [&] {
    body();
    return true;
  });
}

std::istringstream stream_over(rust::Slice<const uint8_t> data) {
  return std::istringstream(
      std::string(reinterpret_cast<const char*>(data.data()), data.size()),
      std::ios_base::in | std::ios_base::binary);
}

rust::Vec<uint8_t> to_rust_bytes(const std::string& bytes) {
  rust::Vec<uint8_t> out;
  out.reserve(bytes.size());
  for (char c : bytes) {
    out.push_back(static_cast<uint8_t>(c));
  }
  return out;
}

uint64_t morton_code(uint16_t x, uint16_t y, uint16_t z) {
  uint64_t code = 0;
  for (unsigned bit = 0; bit < kTreeDepth; ++bit) {
    code |= static_cast<uint64_t>((x >> bit) & 1u) << (3 * bit);
    code |= static_cast<uint64_t>((y >> bit) & 1u) << (3 * bit + 1);
    code |= static_cast<uint64_t>((z >> bit) & 1u) << (3 * bit + 2);
  }
  return code;
}

}  // namespace

ShimTree::ShimTree(double resolution) : octomap::OcTree(resolution) {}

void ShimTree::read_full_stream(std::istream& stream) {
  std::string line;
  std::getline(stream, line);
  if (line.compare(0, fileHeader.length(), fileHeader) != 0) {
    throw std::runtime_error("first line of the file is not \"" + fileHeader + "\"");
  }
  std::string id;
  unsigned size = 0;
  double res = 0.0;
  if (!readHeader(stream, id, size, res)) {
    throw std::runtime_error("OctoMap could not read the file header");
  }
  if (id != getTreeType()) {
    throw std::runtime_error("tree type \"" + id + "\" is not OcTree");
  }
  clear();
  setResolution(res);
  if (size > 0) {
    readData(stream);
  }
}

void ShimTree::insert_leaf(const LeafRecord& leaf) {
  if (leaf.depth > kTreeDepth) {
    throw std::invalid_argument("leaf depth greater than 16");
  }
  const unsigned free_bits = 3 * (kTreeDepth - leaf.depth);
  const uint64_t start = morton_code(leaf.x, leaf.y, leaf.z);
  const uint64_t size = uint64_t{1} << free_bits;
  if ((start & (size - 1)) != 0) {
    throw std::invalid_argument("leaf key is not the first voxel of its node");
  }
  if (has_leaves_ && start < next_free_code_) {
    throw std::invalid_argument("leaves are not in increasing, non-overlapping Morton order");
  }
  if (leaf.depth == 0) {
    if (root != nullptr) {
      throw std::invalid_argument("a root leaf cannot share the tree with other leaves");
    }
    root = new octomap::OcTreeNode();
    tree_size++;
    size_changed = true;
    root->setLogOdds(leaf.log_odds);
  } else {
    if (root == nullptr) {
      root = new octomap::OcTreeNode();
      tree_size++;
      size_changed = true;
    } else if (!nodeHasChildren(root) && has_leaves_) {
      throw std::invalid_argument("a root leaf cannot share the tree with other leaves");
    }
    octomap::OcTreeNode* node = root;
    for (unsigned depth = 0; depth < leaf.depth; ++depth) {
      const unsigned bit = kTreeDepth - 1 - depth;
      const unsigned child = ((leaf.x >> bit) & 1u) | (((leaf.y >> bit) & 1u) << 1) |
                             (((leaf.z >> bit) & 1u) << 2);
      const bool last = depth + 1 == leaf.depth;
      if (nodeChildExists(node, child)) {
        if (last) {
          throw std::invalid_argument("two leaves share a node");
        }
        node = getNodeChild(node, child);
      } else {
        node = createNodeChild(node, child);
      }
    }
    node->setLogOdds(leaf.log_odds);
  }
  has_leaves_ = true;
  next_free_code_ = start + size;
}

void ShimTree::export_leaves_into(rust::Vec<LeafRecord>& out) const {
  if (root != nullptr) {
    export_node(root, 0, 0, 0, 0, out);
  }
}

void ShimTree::export_node(const octomap::OcTreeNode* node, unsigned depth, uint16_t x,
                           uint16_t y, uint16_t z, rust::Vec<LeafRecord>& out) const {
  if (!nodeHasChildren(node)) {
    LeafRecord leaf;
    leaf.x = x;
    leaf.y = y;
    leaf.z = z;
    leaf.depth = static_cast<uint8_t>(depth);
    leaf.log_odds = node->getLogOdds();
    out.push_back(leaf);
    return;
  }
  if (depth >= kTreeDepth) {
    throw std::runtime_error("tree is deeper than 16 levels");
  }
  const unsigned bit = kTreeDepth - 1 - depth;
  for (unsigned child = 0; child < 8; ++child) {
    if (nodeChildExists(node, child)) {
      export_node(getNodeChild(node, child), depth + 1,
                  static_cast<uint16_t>(x | ((child & 1u) << bit)),
                  static_cast<uint16_t>(y | (((child >> 1) & 1u) << bit)),
                  static_cast<uint16_t>(z | (((child >> 2) & 1u) << bit)), out);
    }
  }
}

std::unique_ptr<ShimTree> new_tree(double resolution, rust::Vec<uint8_t>& log) {
  return guarded(log, [&] { return std::make_unique<ShimTree>(resolution); });
}

std::unique_ptr<ShimTree> clone_tree(const ShimTree& tree, rust::Vec<uint8_t>& log) {
  return guarded(log, [&] { return std::make_unique<ShimTree>(tree); });
}

std::unique_ptr<ShimTree> read_binary(rust::Slice<const uint8_t> data, rust::Vec<uint8_t>& log,
                                      bool& complete) {
  return guarded(log, [&] {
    std::istringstream stream = stream_over(data);
    auto tree = std::make_unique<ShimTree>(0.1);
    // readBinary() returns false on a `size` mismatch even though it loaded the whole tree;
    // the caller, which has checked the data, decides what that means.
    complete = tree->readBinary(stream);
    return tree;
  });
}

std::unique_ptr<ShimTree> read_full(rust::Slice<const uint8_t> data, rust::Vec<uint8_t>& log) {
  return guarded(log, [&] {
    std::istringstream stream = stream_over(data);
    auto tree = std::make_unique<ShimTree>(0.1);
    tree->read_full_stream(stream);
    return tree;
  });
}

rust::Vec<uint8_t> write_binary(ShimTree& tree, rust::Vec<uint8_t>& log) {
  return guarded(log, [&] {
    std::ostringstream stream(std::ios_base::out | std::ios_base::binary);
    if (!tree.writeBinary(stream)) {
      throw std::runtime_error("writeBinary failed");
    }
    return to_rust_bytes(stream.str());
  });
}

rust::Vec<uint8_t> write_binary_unchanged(const ShimTree& tree, rust::Vec<uint8_t>& log) {
  return guarded(log, [&] {
    std::ostringstream stream(std::ios_base::out | std::ios_base::binary);
    if (!tree.writeBinaryConst(stream)) {
      throw std::runtime_error("writeBinaryConst failed");
    }
    return to_rust_bytes(stream.str());
  });
}

rust::Vec<uint8_t> write_full(const ShimTree& tree, rust::Vec<uint8_t>& log) {
  return guarded(log, [&] {
    std::ostringstream stream(std::ios_base::out | std::ios_base::binary);
    if (!tree.write(stream) || !stream.good()) {
      throw std::runtime_error("write failed");
    }
    return to_rust_bytes(stream.str());
  });
}

double resolution(const ShimTree& tree) { return tree.getResolution(); }

uint32_t tree_depth(const ShimTree& tree) { return tree.getTreeDepth(); }

uint64_t node_count(const ShimTree& tree) { return tree.size(); }

uint64_t leaf_count(const ShimTree& tree) { return tree.getNumLeafNodes(); }

OccupancyParameters occupancy_parameters(const ShimTree& tree) {
  OccupancyParameters parameters;
  parameters.occupancy_threshold = tree.getOccupancyThres();
  parameters.prob_hit = tree.getProbHit();
  parameters.prob_miss = tree.getProbMiss();
  parameters.clamping_min = tree.getClampingThresMin();
  parameters.clamping_max = tree.getClampingThresMax();
  return parameters;
}

void set_occupancy_parameters(ShimTree& tree, const OccupancyParameters& parameters,
                              rust::Vec<uint8_t>& log) {
  guarded_void(log, [&] {
    tree.setOccupancyThres(parameters.occupancy_threshold);
    tree.setProbHit(parameters.prob_hit);
    tree.setProbMiss(parameters.prob_miss);
    tree.setClampingThresMin(parameters.clamping_min);
    tree.setClampingThresMax(parameters.clamping_max);
  });
}

rust::Vec<LeafRecord> export_leaves(const ShimTree& tree, rust::Vec<uint8_t>& log) {
  return guarded(log, [&] {
    rust::Vec<LeafRecord> out;
    out.reserve(tree.getNumLeafNodes());
    tree.export_leaves_into(out);
    return out;
  });
}

std::unique_ptr<ShimTree> build_tree(double resolution, rust::Slice<const LeafRecord> leaves,
                                     rust::Vec<uint8_t>& log) {
  return guarded(log, [&] {
    auto tree = std::make_unique<ShimTree>(resolution);
    for (const LeafRecord& leaf : leaves) {
      tree->insert_leaf(leaf);
    }
    // Inner nodes take the maximum of their children, as a .bt reader sets them.
    tree->updateInnerOccupancy();
    return tree;
  });
}

bool search(const ShimTree& tree, uint16_t x, uint16_t y, uint16_t z, float& log_odds) {
  const octomap::OcTreeNode* node = tree.search(octomap::OcTreeKey(x, y, z));
  if (node == nullptr) {
    return false;
  }
  log_odds = node->getLogOdds();
  return true;
}

void prune(ShimTree& tree, rust::Vec<uint8_t>& log) {
  guarded_void(log, [&] { tree.prune(); });
}

void expand(ShimTree& tree, rust::Vec<uint8_t>& log) {
  guarded_void(log, [&] { tree.expand(); });
}

void to_max_likelihood(ShimTree& tree, rust::Vec<uint8_t>& log) {
  guarded_void(log, [&] { tree.toMaxLikelihood(); });
}

void update_inner_occupancy(ShimTree& tree, rust::Vec<uint8_t>& log) {
  guarded_void(log, [&] { tree.updateInnerOccupancy(); });
}

}  // namespace froctomap_shim
