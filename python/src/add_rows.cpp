// Problem.add_rows: the numpy rows of one residual function, split into residual blocks by the
// variables each group of rows reads.
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include "carat/base/error.hpp"
#include "numpy_rows_block.hpp"
#include "python_problem.hpp"

namespace carat::python {

namespace {

/// The manifold carat's Python module uses for a kind of variable.
std::shared_ptr<const Manifold> manifold_of(VariableKind kind, int ambient) {
  switch (kind) {
    case VariableKind::kSE3:
      return se3_manifold();
    case VariableKind::kSE2:
      return se2_manifold();
    case VariableKind::kEuclidean:
      break;
  }
  return euclidean_manifold(ambient);
}

/// Whether `function` takes a keyword argument named `jacobians`.
bool takes_jacobians_flag(const py::object& function) {
  try {
    const py::object parameters =
        py::module_::import("inspect").attr("signature")(function).attr("parameters");
    return parameters.attr("__contains__")("jacobians").cast<bool>();
  } catch (py::error_already_set&) {
    return false;  // builtins and the like have no signature: called without the keyword
  }
}

std::string function_name(const py::object& function) {
  if (py::hasattr(function, "__name__")) return py::str(function.attr("__name__"));
  return "add_rows";
}

}  // namespace

py::array_t<int> PythonProblem::add_rows(const py::object& function, const py::handle& variables,
                                         int rows, int group, const std::string& loss,
                                         double loss_scale, const std::string& loss_per,
                                         const std::optional<std::string>& name) {
  check_free();
  if (!PyCallable_Check(function.ptr())) {
    throw py::type_error("add_rows: the residual function is not callable");
  }
  if (rows < 1) throw py::value_error("add_rows: rows must be >= 1, got " + std::to_string(rows));
  if (group < 1 || rows % group != 0) {
    throw py::value_error("add_rows: rows=" + std::to_string(rows) +
                          " is not a whole number of groups of group=" + std::to_string(group));
  }
  if (loss_per != "group" && loss_per != "block") {
    throw py::value_error("add_rows: loss_per must be 'group' or 'block', got '" + loss_per + "'");
  }
  const std::shared_ptr<const LossFunction> robust = loss_argument(loss, loss_scale, "add_rows");
  const int groups = rows / group;
  const std::string label = name ? *name : function_name(function);

  py::list items;
  if (py::isinstance<py::list>(variables) || py::isinstance<py::tuple>(variables)) {
    for (const py::handle item : variables) items.append(item);
  } else {
    items.append(variables);
  }
  if (items.empty()) throw py::value_error("add_rows: needs at least one variable");

  std::vector<RowsSlot> slots(items.size());
  std::vector<RowsVariable> batch_variables;
  // Variable id -> batch variable (-1: none yet).
  std::vector<int> local(static_cast<std::size_t>(problem_.num_variables()), -1);
  const auto local_of = [&](VariableId v) {
    int& batch = local[static_cast<std::size_t>(v.index)];
    if (batch < 0) {
      batch = static_cast<int>(batch_variables.size());
      batch_variables.push_back({v, problem_.value_offset(v), problem_.manifold(v).ambient_size()});
    }
    return batch;
  };
  for (std::size_t j = 0; j < items.size(); ++j) {
    const std::string what = "add_rows argument " + std::to_string(j + 1);
    const py::handle item = items[j];
    RowsSlot& slot = slots[j];
    const auto describe_slot = [&](VariableId v) {
      slot.kind = kind(v);
      slot.ambient = problem_.manifold(v).ambient_size();
      slot.tangent = problem_.manifold(v).tangent_size();
      slot.manifold = manifold_of(slot.kind, slot.ambient);
    };
    const py::array as_array = py::module_::import("numpy").attr("asarray")(item);
    const char type = as_array.dtype().kind();
    if (type != 'i' && type != 'u') {
      throw py::value_error(what + ": expected a variable id or a 1-D array of them, got " +
                            std::string(py::str(py::type::of(item).attr("__name__"))));
    }
    if (as_array.ndim() == 0) {
      const VariableId v = id(as_array.attr("item")().cast<int>(), what);
      describe_slot(v);
      slot.shared = local_of(v);
      continue;
    }
    if (as_array.ndim() != 1 || as_array.shape(0) != groups) {
      throw py::value_error(what + ": expected a variable id or one per group (" +
                            std::to_string(groups) + " ids), got an array of shape " +
                            std::string(py::str(as_array.attr("shape"))));
    }
    const auto ids =
        py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(as_array);
    slot.indexed = true;
    slot.per_group.resize(static_cast<std::size_t>(groups));
    // Kinds are checked once per distinct variable (a camera is read by thousands of groups).
    std::vector<int> seen(static_cast<std::size_t>(problem_.num_variables()), -1);
    for (int g = 0; g < groups; ++g) {
      const std::int64_t raw = ids.data()[g];
      const int index = raw < 0 || raw >= problem_.num_variables() ? -1 : static_cast<int>(raw);
      if (index < 0 || seen[static_cast<std::size_t>(index)] < 0) {
        const VariableId v = id(index, what + "[" + std::to_string(g) + "]");
        if (g == 0) {
          describe_slot(v);
        } else if (kind(v) != slot.kind || problem_.manifold(v).ambient_size() != slot.ambient) {
          throw py::value_error(what + ": mixes variables of kinds " +
                                describe(slot.kind, slot.ambient) + " and " +
                                describe(kind(v), problem_.manifold(v).ambient_size()) +
                                " (group " + std::to_string(g) + ")");
        }
        seen[static_cast<std::size_t>(index)] = local_of(v);
      }
      slot.per_group[static_cast<std::size_t>(g)] = seen[static_cast<std::size_t>(index)];
    }
  }

  // The blocks: one per distinct tuple of variables, in the order of their first group.
  const std::size_t num_slots = slots.size();
  const auto variable_of = [&](std::size_t j, int g) {
    return slots[j].indexed ? slots[j].per_group[static_cast<std::size_t>(g)] : slots[j].shared;
  };
  // Without an indexed argument every group reads the same variables: one block, group 0's.
  bool any_indexed = false;
  for (const RowsSlot& slot : slots) any_indexed = any_indexed || slot.indexed;
  const int scanned = any_indexed ? groups : 1;
  std::vector<int> block_of_group(static_cast<std::size_t>(scanned));
  std::vector<int> first_group;  // per block
  {
    // Each group's first group over the same variables (itself when it starts a block).
    std::vector<int> first_of_group(static_cast<std::size_t>(scanned));
    if (num_slots <= 2) {
      // Without hashing: the groups by their first variable (a counting sort, groups ascending
      // within it), then per first variable a mark per second variable.
      const std::size_t num_batch = batch_variables.size();
      std::vector<int> start(num_batch + 1, 0);
      for (int g = 0; g < scanned; ++g) ++start[static_cast<std::size_t>(variable_of(0, g)) + 1];
      for (std::size_t v = 0; v < num_batch; ++v) start[v + 1] += start[v];
      std::vector<int> by_first(static_cast<std::size_t>(scanned));
      {
        std::vector<int> fill(start.begin(), start.end() - 1);
        for (int g = 0; g < scanned; ++g) {
          by_first[static_cast<std::size_t>(fill[static_cast<std::size_t>(variable_of(0, g))]++)] =
              g;
        }
      }
      std::vector<int> marked(num_batch, -1);  // first variable that last marked it
      std::vector<int> first(num_batch, 0);    // the first group of (that variable, it)
      for (std::size_t a = 0; a < num_batch; ++a) {
        for (int k = start[a]; k < start[a + 1]; ++k) {
          const int g = by_first[static_cast<std::size_t>(k)];
          const auto b = static_cast<std::size_t>(num_slots == 2 ? variable_of(1, g) : 0);
          if (marked[b] != static_cast<int>(a)) {
            marked[b] = static_cast<int>(a);
            first[b] = g;
          }
          first_of_group[static_cast<std::size_t>(g)] = first[b];
        }
      }
    } else {
      // Longer tuples: strings of their bytes as keys.
      std::unordered_map<std::string, int> by_bytes;
      std::string key(num_slots * sizeof(int), '\0');
      for (int g = 0; g < scanned; ++g) {
        for (std::size_t j = 0; j < num_slots; ++j) {
          const int v = variable_of(j, g);
          std::memcpy(key.data() + j * sizeof(int), &v, sizeof(int));
        }
        first_of_group[static_cast<std::size_t>(g)] = by_bytes.emplace(key, g).first->second;
      }
    }
    for (int g = 0; g < scanned; ++g) {
      const int earlier = first_of_group[static_cast<std::size_t>(g)];
      if (earlier != g) {
        block_of_group[static_cast<std::size_t>(g)] =
            block_of_group[static_cast<std::size_t>(earlier)];
        continue;
      }
      for (std::size_t a = 0; a < num_slots; ++a) {
        for (std::size_t b = a + 1; b < num_slots; ++b) {
          if (variable_of(a, g) == variable_of(b, g)) {
            throw py::value_error(
                "add_rows: arguments " + std::to_string(a + 1) + " and " + std::to_string(b + 1) +
                " are the same variable (" +
                std::to_string(
                    batch_variables[static_cast<std::size_t>(variable_of(a, g))].id.index) +
                ") in group " + std::to_string(g) + "; a block's variables must be distinct");
          }
        }
      }
      block_of_group[static_cast<std::size_t>(g)] = static_cast<int>(first_group.size());
      first_group.push_back(g);
    }
  }
  const std::size_t num_blocks = first_group.size();
  // Each block's rows, in group order (a counting sort of the groups by block).
  std::vector<std::size_t> block_start(num_blocks + 1, 0);
  std::vector<int> grouped;
  if (any_indexed) {
    for (int b : block_of_group) ++block_start[static_cast<std::size_t>(b) + 1];
    for (std::size_t b = 0; b < num_blocks; ++b) block_start[b + 1] += block_start[b];
    grouped.resize(static_cast<std::size_t>(groups));
    std::vector<std::size_t> fill(block_start.begin(), block_start.end() - 1);
    for (int g = 0; g < groups; ++g) {
      grouped[fill[static_cast<std::size_t>(block_of_group[static_cast<std::size_t>(g)])]++] = g;
    }
  }

  auto batch = std::make_shared<const NumpyRows>(
      function, label, group, groups, slots, batch_variables,
      loss_per == "group" ? robust : nullptr, errors_, takes_jacobians_flag(function));
  batches_.push_back(batch);
  const std::shared_ptr<const LossFunction> block_loss = loss_per == "block" ? robust : nullptr;
  py::array_t<int> ids(static_cast<py::ssize_t>(num_blocks));
  std::vector<VariableId> variable_ids(num_slots);
  std::vector<int> tuple(num_slots);
  for (std::size_t b = 0; b < num_blocks; ++b) {
    for (std::size_t j = 0; j < num_slots; ++j) {
      tuple[j] = variable_of(j, first_group[b]);
      variable_ids[j] = batch_variables[static_cast<std::size_t>(tuple[j])].id;
    }
    std::vector<int> block_groups;
    if (!batch->single_block()) {
      block_groups.assign(grouped.begin() + static_cast<std::ptrdiff_t>(block_start[b]),
                          grouped.begin() + static_cast<std::ptrdiff_t>(block_start[b + 1]));
    }
    auto block =
        std::make_shared<NumpyRowsBlock>(batch, tuple, std::move(block_groups), std::vector<int>{});
    ids.mutable_data()[b] =
        problem_.add_residual_block(std::move(block), variable_ids, block_loss).index;
  }
  return ids;
}

}  // namespace carat::python
