#include "fibres/pole_frame.h"

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace fascicle {

namespace {

using Complex = std::complex<double>;
constexpr double kInf = std::numeric_limits<double>::infinity();

bool is_infinite(Complex w) { return std::isinf(w.real()) || std::isinf(w.imag()); }

}  // namespace

Complex PoleFrame::stereographic(const Vec3& p) {
  // (x + i y) / (1 + z) == (1 - z) / (x - i y) on the unit sphere; the second form keeps its
  // precision near the south pole, the first near the north pole.
  if (p.z() >= 0.0) return Complex(p.x(), p.y()) / (1.0 + p.z());
  const Complex conj(p.x(), -p.y());
  if (std::abs(conj) == 0.0) return Complex(kInf, kInf);
  return (1.0 - p.z()) / conj;
}

Vec3 PoleFrame::from_stereographic(Complex w) {
  if (is_infinite(w)) return Vec3(0.0, 0.0, -1.0);
  const double a = std::norm(w);
  if (a <= 1.0) {
    const Complex xy = 2.0 * w / (1.0 + a);
    return Vec3(xy.real(), xy.imag(), (1.0 - a) / (1.0 + a)).normalized();
  }
  const Complex u = 1.0 / w;  // |u| < 1
  const double b = std::norm(u);
  const Complex xy = 2.0 * std::conj(u) / (b + 1.0);
  return Vec3(xy.real(), xy.imag(), (b - 1.0) / (b + 1.0)).normalized();
}

PoleFrame::PoleFrame(const Vec3& origin, const Vec3& insertion, double scale) {
  if (!origin.allFinite() || !insertion.allFinite() || origin.norm() == 0.0 || insertion.norm() == 0.0)
    throw std::invalid_argument("PoleFrame: origin and insertion must be finite non-zero vectors");
  const Vec3 o = origin.normalized();
  const Vec3 i = insertion.normalized();
  if (std::atan2(o.cross(i).norm(), o.dot(i)) < 1e-9)
    throw std::invalid_argument("PoleFrame: origin and insertion coincide");
  rotation_ = Eigen::Quaterniond::FromTwoVectors(o, Vec3(0.0, 0.0, 1.0)).toRotationMatrix();
  const Vec3 q = (rotation_ * i).normalized();
  const Complex w = stereographic(q);
  moebius_ = !is_infinite(w) && std::abs(w) < 1e15;
  pole_ = moebius_ ? w : Complex(0.0, 0.0);
  set_scale(scale);
}

void PoleFrame::set_scale(double scale) {
  if (!(scale > 0.0) || !std::isfinite(scale)) throw std::invalid_argument("PoleFrame: scale must be > 0");
  scale_ = scale;
}

Vec3 PoleFrame::to_pole(const Vec3& p) const {
  const Vec3 r = rotation_ * p.normalized();
  Complex w = stereographic(r);
  Complex m;
  if (!moebius_) {
    m = w;
  } else if (is_infinite(w)) {
    m = -pole_;  // the south pole goes to -pole
  } else if (w == pole_) {
    return Vec3(0.0, 0.0, -1.0);
  } else {
    m = w * pole_ / (pole_ - w);
  }
  if (is_infinite(m)) return Vec3(0.0, 0.0, -1.0);
  return from_stereographic(m * scale_);
}

Vec3 PoleFrame::from_pole(const Vec3& q) const {
  const Complex m0 = stereographic(q.normalized());
  Vec3 r;
  if (is_infinite(m0)) {
    r = moebius_ ? from_stereographic(pole_) : Vec3(0.0, 0.0, -1.0);
  } else {
    const Complex m = m0 / scale_;
    if (!moebius_) {
      r = from_stereographic(m);
    } else if (m == -pole_) {
      r = Vec3(0.0, 0.0, -1.0);
    } else {
      r = from_stereographic(m * pole_ / (pole_ + m));
    }
  }
  return (rotation_.transpose() * r).normalized();
}

}  // namespace fascicle
