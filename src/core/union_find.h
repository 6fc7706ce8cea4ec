// find_root: the root of x in a union-find forest stored as a parent array, with path halving
// (each visited node is pointed at its grandparent). How two roots are joined is left to the
// caller, because the callers' outputs depend on which root survives.
#pragma once

#include <vector>

namespace typemerge::core {

template <typename Index>
Index find_root(std::vector<Index>& parent, Index x) {
  while (parent[x] != x) {
    parent[x] = parent[parent[x]];
    x = parent[x];
  }
  return x;
}

}  // namespace typemerge::core
