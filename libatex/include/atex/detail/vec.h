// Tiny fixed-size vectors and matrices for the ATEX_HD mathematics (render
// projection, SH, textures). Plain aggregates: `Vec3<T> a{}` is zero, element
// access by [i] / (row, col); matrices are row-major. No allocation, no Eigen,
// so that nvcc compiles them for the device unchanged.
#pragma once

#include "atex/hd.h"

namespace atex::detail {

template <typename T>
struct Vec2 {
  T v[2];
  ATEX_HD T& operator[](int i) { return v[i]; }
  ATEX_HD const T& operator[](int i) const { return v[i]; }
};

template <typename T>
struct Vec3 {
  T v[3];
  ATEX_HD T& operator[](int i) { return v[i]; }
  ATEX_HD const T& operator[](int i) const { return v[i]; }
};

template <typename T>
struct Vec4 {
  T v[4];
  ATEX_HD T& operator[](int i) { return v[i]; }
  ATEX_HD const T& operator[](int i) const { return v[i]; }
};

// Row-major 2x2.
template <typename T>
struct Mat2 {
  T m[2][2];
  ATEX_HD T& operator()(int r, int c) { return m[r][c]; }
  ATEX_HD const T& operator()(int r, int c) const { return m[r][c]; }
};

// Row-major 3x3.
template <typename T>
struct Mat3 {
  T m[3][3];
  ATEX_HD T& operator()(int r, int c) { return m[r][c]; }
  ATEX_HD const T& operator()(int r, int c) const { return m[r][c]; }
};

// Row-major 2x3 (the EWA Jacobian).
template <typename T>
struct Mat23 {
  T m[2][3];
  ATEX_HD T& operator()(int r, int c) { return m[r][c]; }
  ATEX_HD const T& operator()(int r, int c) const { return m[r][c]; }
};

// ---- Vec3 ------------------------------------------------------------------
template <typename T>
ATEX_HD Vec3<T> operator+(const Vec3<T>& a, const Vec3<T>& b) {
  return {{a[0] + b[0], a[1] + b[1], a[2] + b[2]}};
}
template <typename T>
ATEX_HD Vec3<T> operator-(const Vec3<T>& a, const Vec3<T>& b) {
  return {{a[0] - b[0], a[1] - b[1], a[2] - b[2]}};
}
template <typename T>
ATEX_HD Vec3<T> operator*(T s, const Vec3<T>& a) {
  return {{s * a[0], s * a[1], s * a[2]}};
}
template <typename T>
ATEX_HD Vec3<T>& operator+=(Vec3<T>& a, const Vec3<T>& b) {
  a[0] += b[0];
  a[1] += b[1];
  a[2] += b[2];
  return a;
}
template <typename T>
ATEX_HD T Dot(const Vec3<T>& a, const Vec3<T>& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

// ---- Mat3 ------------------------------------------------------------------
template <typename T>
ATEX_HD Mat3<T> Transpose(const Mat3<T>& a) {
  Mat3<T> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r(i, j) = a(j, i);
  return r;
}
template <typename T>
ATEX_HD Mat3<T> operator*(const Mat3<T>& a, const Mat3<T>& b) {
  Mat3<T> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r(i, j) = a(i, 0) * b(0, j) + a(i, 1) * b(1, j) + a(i, 2) * b(2, j);
  return r;
}
template <typename T>
ATEX_HD Mat3<T> operator+(const Mat3<T>& a, const Mat3<T>& b) {
  Mat3<T> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r(i, j) = a(i, j) + b(i, j);
  return r;
}
template <typename T>
ATEX_HD Mat3<T>& operator+=(Mat3<T>& a, const Mat3<T>& b) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) a(i, j) += b(i, j);
  return a;
}
template <typename T>
ATEX_HD Vec3<T> operator*(const Mat3<T>& a, const Vec3<T>& x) {
  return {{a(0, 0) * x[0] + a(0, 1) * x[1] + a(0, 2) * x[2], a(1, 0) * x[0] + a(1, 1) * x[1] + a(1, 2) * x[2],
           a(2, 0) * x[0] + a(2, 1) * x[1] + a(2, 2) * x[2]}};
}
// aᵀ·x without forming the transpose.
template <typename T>
ATEX_HD Vec3<T> TransposeTimes(const Mat3<T>& a, const Vec3<T>& x) {
  return {{a(0, 0) * x[0] + a(1, 0) * x[1] + a(2, 0) * x[2], a(0, 1) * x[0] + a(1, 1) * x[1] + a(2, 1) * x[2],
           a(0, 2) * x[0] + a(1, 2) * x[1] + a(2, 2) * x[2]}};
}
// Column k of a (for a rotation: local axis k in world coordinates).
template <typename T>
ATEX_HD Vec3<T> Column(const Mat3<T>& a, int k) {
  return {{a(0, k), a(1, k), a(2, k)}};
}
// a(:, k) += x.
template <typename T>
ATEX_HD void AddToColumn(Mat3<T>& a, int k, const Vec3<T>& x) {
  a(0, k) += x[0];
  a(1, k) += x[1];
  a(2, k) += x[2];
}
template <typename T>
ATEX_HD Mat3<T> ZeroMat3() {
  Mat3<T> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r(i, j) = T(0);
  return r;
}

}  // namespace atex::detail
