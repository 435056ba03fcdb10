#include "fill_estimate.hpp"

#include <cholmod.h>

#include <algorithm>
#include <string>

#include "carat/base/error.hpp"
#include "cholmod_session.hpp"

namespace carat::internal {

FillEstimate estimate_fill(const BlockGraph& graph, double stop_after) {
  FillEstimate out;
  const std::size_t n = graph.dims.size();
  std::size_t edges = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const double d = graph.dims[k];
    out.matrix_entries += d * (d + 1.0) / 2.0;
    for (const int j : graph.neighbours[k]) {
      if (static_cast<std::size_t>(j) < k)
        out.matrix_entries += d * graph.dims[static_cast<std::size_t>(j)];
    }
    edges += graph.neighbours[k].size();
  }
  if (n == 0) return out;
  // AMD on the block graph (CHOLMOD reads the upper part of a symmetric pattern).
  std::vector<SuiteSparse_long> position(n);
  for (std::size_t k = 0; k < n; ++k) position[k] = static_cast<SuiteSparse_long>(k);
  if (n > 1) {
    CholmodSession session;
    cholmod_common& common = session.common();
    cholmod_sparse* G =
        cholmod_l_allocate_sparse(n, n, edges + n, 1, 1, 1, CHOLMOD_PATTERN, &common);
    if (!G)
      throw Error("fill estimate: out of memory while ordering " + std::to_string(n) + " nodes");
    auto* Gp = static_cast<SuiteSparse_long*>(G->p);
    auto* Gi = static_cast<SuiteSparse_long*>(G->i);
    Gp[0] = 0;
    for (std::size_t k = 0; k < n; ++k) {
      std::vector<SuiteSparse_long> column(graph.neighbours[k].begin(), graph.neighbours[k].end());
      column.push_back(static_cast<SuiteSparse_long>(k));
      std::sort(column.begin(), column.end());
      column.erase(std::unique(column.begin(), column.end()), column.end());
      std::copy(column.begin(), column.end(), Gi + Gp[k]);
      Gp[k + 1] = Gp[k] + static_cast<SuiteSparse_long>(column.size());
    }
    common.supernodal = CHOLMOD_SIMPLICIAL;
    common.nmethods = 1;
    common.method[0].ordering = CHOLMOD_AMD;
    common.postorder = 1;
    cholmod_factor* L = cholmod_l_analyze(G, &common);
    cholmod_l_free_sparse(&G, &common);
    if (!L) {
      throw Error("fill estimate: ordering failed (CHOLMOD status " +
                  std::to_string(common.status) + ")");
    }
    const auto* perm = static_cast<const SuiteSparse_long*>(L->Perm);
    for (std::size_t k = 0; k < n; ++k)
      position[static_cast<std::size_t>(perm[k])] = static_cast<SuiteSparse_long>(k);
    cholmod_l_free_factor(&L, &common);
  }
  // Node at each elimination step, and the elimination tree of the permuted pattern.
  std::vector<int> node(n);
  for (std::size_t k = 0; k < n; ++k)
    node[static_cast<std::size_t>(position[k])] = static_cast<int>(k);
  std::vector<int> parent(n, -1), ancestor(n, -1);
  for (std::size_t k = 0; k < n; ++k) {
    for (const int neighbour : graph.neighbours[static_cast<std::size_t>(node[k])]) {
      auto i = static_cast<int>(position[static_cast<std::size_t>(neighbour)]);
      while (i >= 0 && i < static_cast<int>(k)) {
        const int next = ancestor[static_cast<std::size_t>(i)];
        ancestor[static_cast<std::size_t>(i)] = static_cast<int>(k);
        if (next < 0) {
          parent[static_cast<std::size_t>(i)] = static_cast<int>(k);
          break;
        }
        i = next;
      }
    }
  }
  // Row k of L: the tree paths from each earlier neighbour up to k, each node once.
  std::vector<int> mark(n, -1);
  for (std::size_t k = 0; k < n; ++k) {
    const double dk = graph.dims[static_cast<std::size_t>(node[k])];
    out.factor_entries += dk * (dk + 1.0) / 2.0;
    mark[k] = static_cast<int>(k);
    for (const int neighbour : graph.neighbours[static_cast<std::size_t>(node[k])]) {
      for (auto i = static_cast<int>(position[static_cast<std::size_t>(neighbour)]);
           i >= 0 && i < static_cast<int>(k) &&
           mark[static_cast<std::size_t>(i)] != static_cast<int>(k);
           i = parent[static_cast<std::size_t>(i)]) {
        mark[static_cast<std::size_t>(i)] = static_cast<int>(k);
        out.factor_entries +=
            dk * graph.dims[static_cast<std::size_t>(node[static_cast<std::size_t>(i)])];
      }
    }
    if (out.factor_entries > stop_after) break;
  }
  return out;
}

}  // namespace carat::internal
