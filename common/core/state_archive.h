// A live object's state as bytes and back, for moving a session to another process (live
// migration, server/cluster/: a draining node hands its sessions' simulations to other nodes).
//
// A type lists its state once, for both directions (the cereal / Boost.Serialization idiom):
//
//   template <class A> void Persist(A& a) { a(x_, v_, armed_); }
//
// StateWriter appends each value's bytes; StateReader reads them back into the same members in
// the same order. Values: arithmetic types and enums (their bytes), Eigen's fixed-size matrices
// and quaternions (their coefficients), std::vector and C arrays of any of these, std::string,
// and any type with Persist. Why our own and not Boost.Serialization or protobuf: the state is
// the private members of a dozen physics types, listed where they are declared; Boost's archives
// would put its headers into common/ (we keep them light), and a protobuf message per type would
// copy each list into a schema that must then be kept in step by hand. The bytes go between two
// processes of one site built from one version (the snapshot's header says which, and a reader of
// another version refuses it), on one architecture; they are not a file format.
//
// The reader is for bytes from another process, so it trusts nothing: every read is bounds
// checked, a vector that already has elements must be read at exactly that size (a model's state
// sized at its Create: a snapshot of another mesh is refused, never resized into it), an empty
// one is read at most at what the remaining bytes can hold, and non-finite floating-point values
// are refused unless the type allows them. After a failed read `ok()` is false and the object
// holds an unspecified mix of old and new state: the caller discards it.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace vsurg {

namespace archive_detail {
template <class T>
concept Scalar = std::is_arithmetic_v<T> || std::is_enum_v<T>;
template <class T>
concept Dense = requires(T& t) {
  t.data();
  T::SizeAtCompileTime;
}
&&(T::SizeAtCompileTime > 0);
template <class T>
concept Quaternion = requires(T& t) {
  t.coeffs();
  t.w();
};
}  // namespace archive_detail

class StateWriter {
 public:
  template <class... T>
  void operator()(const T&... values) {
    (Put(values), ...);
  }
  const std::string& bytes() const { return bytes_; }
  std::string Take() { return std::move(bytes_); }

 private:
  template <class T>
  void Put(const T& v) {
    if constexpr (archive_detail::Scalar<T>) {
      const size_t at = bytes_.size();
      bytes_.resize(at + sizeof(T));
      std::memcpy(bytes_.data() + at, &v, sizeof(T));
    } else if constexpr (archive_detail::Quaternion<T>) {
      Put(v.coeffs());
    } else if constexpr (archive_detail::Dense<T>) {
      for (int i = 0; i < T::SizeAtCompileTime; ++i) Put(v.data()[i]);
    } else if constexpr (std::is_same_v<T, std::string>) {
      Put(static_cast<uint64_t>(v.size()));
      bytes_.append(v);
    } else if constexpr (std::is_array_v<T>) {
      for (const auto& e : v) Put(e);
    } else if constexpr (requires {
                           v.size();
                           v.begin();
                           typename T::value_type;
                         }) {
      Put(static_cast<uint64_t>(v.size()));
      for (const auto& e : v) Put(e);
    } else {
      // Persist lists the members for both directions; writing only reads them.
      const_cast<T&>(v).Persist(*this);
    }
  }
  std::string bytes_;
};

class StateReader {
 public:
  explicit StateReader(std::string_view bytes) : bytes_(bytes) {}
  template <class... T>
  void operator()(T&... values) {
    (Get(values), ...);
  }
  bool ok() const { return ok_; }
  // Read without error, and to the last byte.
  bool done() const { return ok_ && at_ == bytes_.size(); }
  void Fail() { ok_ = false; }
  // Floating-point values that may be infinite (a distance not yet known): allowed while set.
  void AllowInfinite(bool allow) { allow_infinite_ = allow; }

 private:
  template <class T>
  void Get(T& v) {
    if (!ok_) return;
    if constexpr (archive_detail::Scalar<T>) {
      if (bytes_.size() - at_ < sizeof(T)) return Fail();
      if constexpr (std::is_same_v<T, bool>) {  // checked before it is a bool: 0 or 1 only
        const auto b = static_cast<unsigned char>(bytes_[at_]);
        if (b > 1) return Fail();
      }
      T x;
      std::memcpy(&x, bytes_.data() + at_, sizeof(T));
      at_ += sizeof(T);
      if constexpr (std::is_floating_point_v<T>) {
        if (std::isnan(x) || (!allow_infinite_ && std::isinf(x))) return Fail();
      }
      v = x;
    } else if constexpr (archive_detail::Quaternion<T>) {
      Get(v.coeffs());
    } else if constexpr (archive_detail::Dense<T>) {
      for (int i = 0; i < T::SizeAtCompileTime; ++i) Get(v.data()[i]);
    } else if constexpr (std::is_same_v<T, std::string>) {
      uint64_t n = 0;
      Get(n);
      if (!ok_ || n > bytes_.size() - at_) return Fail();
      v.assign(bytes_.data() + at_, n);
      at_ += n;
    } else if constexpr (std::is_array_v<T>) {
      for (auto& e : v) Get(e);
    } else if constexpr (requires {
                           v.size();
                           v.resize(0);
                           typename T::value_type;
                         }) {
      uint64_t n = 0;
      Get(n);
      if (!ok_) return;
      if (!v.empty()) {
        if (n != v.size()) return Fail();
      } else {
        if (n > bytes_.size() - at_) return Fail();  // each element takes at least a byte
        v.resize(n);
      }
      for (auto& e : v) Get(e);
    } else {
      v.Persist(*this);
    }
  }
  std::string_view bytes_;
  size_t at_ = 0;
  bool ok_ = true;
  bool allow_infinite_ = false;
};

}  // namespace vsurg
