#pragma once

/// Integer arguments that name themselves when out of range. pybind11 refuses a Python int that
/// does not fit the C++ parameter (`seed=-1` for an unsigned seed, `target=2**40` for an int)
/// with "incompatible function arguments", naming no argument. Functions defined through
/// def_checked() / init_checked() take every integer parameter as any Python integer (an int or
/// a numpy integer; never a bool or a float) and convert it when the call starts, raising
/// ValueError "seed: must be an integer in [0, 18446744073709551615], got -1".

#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace carat::python {

namespace py = pybind11;

/// A Python integer as passed, for an integer parameter of type T (converted by to_integer()).
template <typename T>
struct IntegerArgument {
  py::object value;  ///< the int (or numpy integer) as passed
};

/// `value` as a T; ValueError naming `name` and T's range when it does not fit.
template <typename T>
T to_integer(const py::object& value, const std::string& name) {
  const py::int_ number = py::reinterpret_steal<py::int_>(PyNumber_Index(value.ptr()));
  if (!number) throw py::error_already_set();
  const auto fail = [&] {
    throw py::value_error(name + ": must be an integer in [" +
                          std::to_string(std::numeric_limits<T>::min()) + ", " +
                          std::to_string(std::numeric_limits<T>::max()) + "], got " +
                          py::repr(number).cast<std::string>().substr(0, 40));
  };
  if constexpr (std::is_signed_v<T>) {
    int overflow = 0;
    const long long v = PyLong_AsLongLongAndOverflow(number.ptr(), &overflow);
    if (overflow != 0 || v < std::numeric_limits<T>::min() || v > std::numeric_limits<T>::max()) {
      fail();
    }
    return static_cast<T>(v);
  } else {
    if (PyObject_RichCompareBool(number.ptr(), py::int_(0).ptr(), Py_LT) == 1) fail();
    const unsigned long long v = PyLong_AsUnsignedLongLong(number.ptr());
    if (PyErr_Occurred() != nullptr) {
      PyErr_Clear();
      fail();
    }
    if (v > std::numeric_limits<T>::max()) fail();
    return static_cast<T>(v);
  }
}

namespace detail {

template <typename T>
constexpr bool is_integer_v = std::is_integral_v<T> && !std::is_same_v<T, bool>;

/// The parameter type a wrapped function takes for a parameter declared as A, and how the value
/// becomes an A again.
template <typename A, typename D = std::decay_t<A>>
struct Parameter {
  using type = A;
  static A&& unwrap(A&& value, const std::string&) { return std::forward<A>(value); }
};
template <typename A, typename D>
requires is_integer_v<D>
struct Parameter<A, D> {
  using type = IntegerArgument<D>;
  static D unwrap(type&& value, const std::string& name) {
    return to_integer<D>(value.value, name);
  }
};
template <typename A, typename T>
requires is_integer_v<T>
struct Parameter<A, std::optional<T>> {
  using type = std::optional<IntegerArgument<T>>;
  static std::optional<T> unwrap(type&& value, const std::string& name) {
    if (!value) return std::nullopt;
    return to_integer<T>(value->value, name);
  }
};

/// The names of the py::arg entries among `extra`, in order.
template <typename... Extra>
std::vector<std::string> argument_names(const Extra&... extra) {
  std::vector<std::string> names;
  (
      [&](const auto& e) {
        if constexpr (std::is_base_of_v<py::arg, std::decay_t<decltype(e)>>) {
          names.emplace_back(e.name);
        }
      }(extra),
      ...);
  return names;
}

template <typename F, typename Signature>
struct Wrapper;
template <typename F, typename R, typename... A>
struct Wrapper<F, R(A...)> {
  /// f with every integer parameter taken as a Python integer, named from `names`.
  static auto wrap(F f, std::vector<std::string> names) {
    names.resize(sizeof...(A));
    return
        [f = std::move(f), names = std::move(names)](typename Parameter<A>::type... values) -> R {
          return call(f, names, std::index_sequence_for<A...>{},
                      std::forward<typename Parameter<A>::type>(values)...);
        };
  }

 private:
  template <std::size_t... I>
  static R call(const F& f, const std::vector<std::string>& names, std::index_sequence<I...>,
                typename Parameter<A>::type&&... values) {
    return f(Parameter<A>::unwrap(std::forward<typename Parameter<A>::type>(values), names[I])...);
  }
};

/// f's call signature R(A...) (a function pointer or a non-generic lambda).
template <typename F>
using signature_t = py::detail::function_signature_t<std::decay_t<F>>;

}  // namespace detail

/// m.def(name, f, extra...) with f's integer parameters checked by name (see above).
template <typename F, typename... Extra>
void def_checked(py::module_& m, const char* name, F&& f, const Extra&... extra) {
  using W = detail::Wrapper<std::decay_t<F>, detail::signature_t<F>>;
  m.def(name, W::wrap(std::forward<F>(f), detail::argument_names(extra...)), extra...);
}

/// cls.def(py::init(factory), extra...) with the factory's integer parameters checked by name.
template <typename Class, typename F, typename... Extra>
Class& init_checked(Class& cls, F&& factory, const Extra&... extra) {
  using W = detail::Wrapper<std::decay_t<F>, detail::signature_t<F>>;
  return cls.def(py::init(W::wrap(std::forward<F>(factory), detail::argument_names(extra...))),
                 extra...);
}

}  // namespace carat::python

namespace pybind11::detail {

/// Loads any Python integer (int or an object with __index__, e.g. numpy.int64; not bool) into
/// IntegerArgument<T>; the conversion to T, with its range check, comes later.
template <typename T>
struct type_caster<carat::python::IntegerArgument<T>> {
  PYBIND11_TYPE_CASTER(carat::python::IntegerArgument<T>, const_name("int"));

  bool load(handle src, bool) {
    if (!src || PyBool_Check(src.ptr()) || PyFloat_Check(src.ptr()) || !PyIndex_Check(src.ptr())) {
      return false;
    }
    value.value = reinterpret_borrow<object>(src);
    return true;
  }

  static handle cast(const carat::python::IntegerArgument<T>& src, return_value_policy, handle) {
    return src.value.inc_ref();
  }
};

}  // namespace pybind11::detail
