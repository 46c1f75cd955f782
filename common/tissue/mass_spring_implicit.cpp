// MassSpringModel's implicit Euler step, in five stages (the guess, the springs' pass, the
// preconditioner, the conjugate gradient with its product, the update). The measured reasons for
// each shape below (and the alternatives that lost) are in docs/BENCHMARKS.md, "The implicit
// step's shape".
//
// Baraff & Witkin 1998, one Newton step of backward Euler:
//   (M + h C + h² K) Δv = h (f₀ − h K v₀),   v₁ = v₀ + Δv,   x₁ = x₀ + h v₁.
// Spring s contributes K_s = k [(1 − α) l̂l̂ᵀ + α I], α = max(0, 1 − L/|l|) (transverse term
// clamped: SPD), and C_s = c l̂l̂ᵀ. The system is never assembled: each spring keeps its block
// B_s = h C_s + h² K_s = a_s l̂l̂ᵀ + b_s I, and the product is a pass over the springs. An anchor
// (a zero-length spring-damper to a fixed point, f = k (target − x) − c v) adds (h c + h² k) I to
// its particle's diagonal block.
//
// With w = v_j − v_i and e = Δv₀_i − Δv₀_j, spring s adds to end i (end j: the negative)
//   g = h [k (|l| − L) + c l̂·w] l̂ + h² K_s w = (h k (|l| − L) + a l̂·w) l̂ + b w   to rhs,
//   t = B_s e = a (l̂·e) l̂ + b e                                                 to A Δv₀,
// and a l̂² + b to both ends' diagonals. (w, −e) is the difference of the ends' state pairs
// (v₀, Δv₀), so (g, −t) comes out of the same three operations, the impulse only in the first half.
//
// The solve is Jacobi-preconditioned CG, warm-started from Δv₀ and filtered (Baraff & Witkin):
// the rows of fixed and driven particles are zero, so their Δv stays 0.
//
// The per-particle vectors are 4 doubles (the fourth always 0; the layout is noted on the
// members in mass_spring.h) and the arithmetic uses GCC's vector extension, so one instruction
// does a 3-vector: each stage is built for AVX-512, AVX2 and the baseline, and the loader picks.
// Each stage takes plain pointers to the members' data: the vector types may alias anything, so
// a member's data() would be read again after every store through them.
#include <algorithm>
#include <bit>
#include <cmath>

#include "common/tissue/extrapolation.h"
#include "common/tissue/mass_spring.h"
#include "common/tissue/simd.h"

namespace vsurg::tissue {

using simd::Dot;
using simd::V4;
using simd::V8;

namespace {
V4* View(std::vector<simd::Lane4>& a) {
  return reinterpret_cast<V4*>(a.data());
}
}  // namespace

bool MassSpringModel::StepImplicit(double h) {
  const bool refresh_diag = solver_springs_stale_ || diag_age_ >= kDiagEvery || h != diag_h_;
  if (solver_springs_stale_) SelectSolverSprings();
  PlaceKinematic(x_, v_, 0.0, h);
  ImplicitGuess(h, refresh_diag);
  ImplicitSprings(h, refresh_diag);
  ImplicitPreconditioner(h, refresh_diag);
  cg_iterations_ = ImplicitSolve(h);
  PlaceKinematic(x_, v_, 1.0, h);
  return ImplicitUpdate(h);
}

// Stage 1, over the particles. Δv's first guess, extrapolated from the last steps' Δv by the
// polynomial of the degree (1 to 3) that would have guessed the last step's Δv best, judged every
// kJudgeEvery steps against Δv₋₁ (still in dv_) from Δv₋₂..Δv₋₅; zero where there is no unknown
// (also for a particle fixed since the last step: the product with the guess must not see its old
// Δv). Starts the pairs the springs' pass sums into: (h (f_ext + m g), −M Δv₀) for (rhs, −A Δv₀),
// the state (v₀, Δv₀), and the preconditioner's diagonal (M, or last step's reciprocal when the
// springs' diagonal is kept). The oldest history buffer (Δv₋₅) takes Δv₋₁ and becomes the newest.
VSURG_SIMD_CLONES
void MassSpringModel::ImplicitGuess(double h, bool refresh_diag) {
  const int n = static_cast<int>(x_.size());
  V4 *const dv = View(dv_), *const pre = View(precond_), *const pos = View(pos_),
            *const inv_diag = View(inv_diag_);
  V8 *const state = reinterpret_cast<V8*>(state_.data()), *const sums =
                                                              reinterpret_cast<V8*>(sums_.data());
  V4* const state_v = reinterpret_cast<V4*>(state_.data());  // state[i]'s v₀ is state_v[2 i]
  const double* const mass = sys_.masses.data();
  const bool lanes = lanes_;
  V4* const o1 = View(history_[h_]);            // Δv₋₂
  V4* const o2 = View(history_[(h_ + 3) % 4]);  // Δv₋₃
  V4* const o3 = View(history_[(h_ + 2) % 4]);  // Δv₋₄
  V4* const o4 = View(history_[(h_ + 1) % 4]);  // Δv₋₅, overwritten with Δv₋₁
  h_ = (h_ + 1) % 4;
  const int degree = last_extrapolation_ = extrapolation_;
  const V4 gravity{params_.gravity.x(), params_.gravity.y(), params_.gravity.z(), 0.0};
  constrained_.clear();
  const bool judge = ++judge_age_ >= kJudgeEvery;
  if (judge) judge_age_ = 0;
  V4 miss1{}, miss2{}, miss3{};  // each degree's squared error on Δv₋₁
  for (int i = 0; i < n; ++i) {
    const V4 last = dv[i];
    V4 d{};
    if (role_[i] != Role::kFree) {
      constrained_.push_back(i);  // capacity reserved: no allocation
      o4[i] = V4{};
    } else {
      if (judge) {
        V4 e1, e2, e3;
        Extrapolate(e1, 1, o1[i], o2[i], o3[i], o4[i]);
        Extrapolate(e2, 2, o1[i], o2[i], o3[i], o4[i]);
        Extrapolate(e3, 3, o1[i], o2[i], o3[i], o4[i]);
        e1 -= last, e2 -= last, e3 -= last;
        miss1 += e1 * e1, miss2 += e2 * e2, miss3 += e3 * e3;
      }
      Extrapolate(d, degree, last, o1[i], o2[i], o3[i]);
      o4[i] = last;
    }
    dv[i] = d;
    const double m = mass[i];
    const V4 f = h * (V4{f_ext_[i].x(), f_ext_[i].y(), f_ext_[i].z(), 0.0} + m * gravity);
    const V4 mdv = -m * d;
    sums[i] = __builtin_shufflevector(f, mdv, 0, 1, 2, 3, 4, 5, 6, 7);
    if (refresh_diag) {
      pre[i] = V4{m, m, m, 1.0};  // the fourth 1: the reciprocal stays finite
    } else {
      pre[i] = inv_diag[i];
    }
    if (lanes && role_[i] == Role::kFree) {
      state_v[2 * i + 1] = d;  // v₀ is there from the last update
    } else {  // placed by PlaceKinematic, or the lanes not kept since the last implicit step
      const V4 v{v_[i].x(), v_[i].y(), v_[i].z(), 0.0};
      state[i] = __builtin_shufflevector(v, d, 0, 1, 2, 3, 4, 5, 6, 7);
      pos[i] = V4{x_[i].x(), x_[i].y(), x_[i].z(), 0.0};
    }
  }
  if (judge)
    extrapolation_ = BestDegree(simd::Sum(miss1), simd::Sum(miss2), simd::Sum(miss3),
                                params_.cg_extrapolation);  // the next steps'
}

// Stage 2, one pass over the springs in chunks that stay in L1, three loops a chunk: the spring
// vectors l and |l|²; then 1/|l|, the block's scalars a = h c + h² k (1 − α), b = h² k α and the
// impulse h k (|l| − L) (vectorised: no scatter); then the sums into both ends (g into rhs, t
// into A Δv₀, the diagonal on the steps that refresh it). The springs are sorted by first end,
// whose sums stay in registers while its springs pass.
//
// 1/|l| is Newton's iteration from the exponent-halving first guess (relative error 3.4%, squared
// each iteration: after four, 3e-16, as close as sqrt and division give): fourteen multiply-adds
// in place of a square root and a division. 1e-300 keeps a zero length finite and is below the
// rounding of any length kept; a spring shorter than kMinLength is zeroed by a factor, since GCC
// (trapping math) vectorises no select of a computed value.
VSURG_SIMD_CLONES
void MassSpringModel::ImplicitSprings(double h, bool refresh_diag) {
  V4 *const pre = View(precond_), *const pos = View(pos_), *const dirs = View(dirs_);
  V8 *const state = reinterpret_cast<V8*>(state_.data()), *const sums =
                                                              reinterpret_cast<V8*>(sums_.data());
  const SpringEnds* const ends = ends_.data();
  double *const coef_a = coef_a_.data(), *const coef_b = coef_b_.data();
  const double *const rest = rest_.data(), *const stiffness = stiffness_.data(),
                      *const damping = damping_.data();
  const size_t ns = ends_.size();
  constexpr size_t kChunk = 256;
  double len2[kChunk], inv_len[kChunk], impulse[kChunk];
  const V4 xyz{1.0, 1.0, 1.0, 0.0};
  int cur = -1;
  V8 si{}, acc{};
  V4 pi{};
  for (size_t c0 = 0; c0 < ns; c0 += kChunk) {
    const size_t cn = std::min(kChunk, ns - c0);
    for (size_t k = 0; k < cn; ++k) {
      const V4 l = pos[ends[c0 + k].j] - pos[ends[c0 + k].i];
      dirs[c0 + k] = l;
      len2[k] = Dot(l, l);
    }
    for (size_t k = 0; k < cn; ++k) {
      const size_t s = c0 + k;
      const double x = len2[k] + 1e-300, half = 0.5 * x;
      double y = std::bit_cast<double>(0x5FE6EB50C7B537A9u - (std::bit_cast<uint64_t>(x) >> 1));
      for (int it = 0; it < 4; ++it) y *= 1.5 - half * y * y;
      const double on = len2[k] >= kMinLength * kMinLength ? 1.0 : 0.0;
      const double inv = on * y;
      const double alpha = std::max(0.0, 1.0 - rest[s] * inv);
      const double hk = h * stiffness[s];
      inv_len[k] = inv;
      coef_a[s] = on * (h * damping[s] + h * hk * (1.0 - alpha));
      coef_b[s] = on * (h * hk * alpha);
      impulse[k] = on * (hk * (len2[k] * inv - rest[s]));
    }
    for (size_t k = 0; k < cn; ++k) {
      const size_t s = c0 + k;
      const int j = ends[s].j;
      if (ends[s].i != cur) {
        if (cur >= 0) sums[cur] += acc, pre[cur] += pi;
        cur = ends[s].i;
        si = state[cur];
        acc = V8{};
        pi = V4{};
      }
      const V4 d = inv_len[k] * dirs[s];
      dirs[s] = d;
      const V8 d2 = __builtin_shufflevector(d, d, 0, 1, 2, 3, 0, 1, 2, 3);
      const double a = coef_a[s], b = coef_b[s], imp = impulse[k];
      const V8 w = state[j] - si;
      V8 dots;
      simd::HalfDots(dots, w, d2);
      const V8 g = (a * dots + V8{imp, imp, imp, imp, 0.0, 0.0, 0.0, 0.0}) * d2 + b * w;
      acc += g;
      sums[j] -= g;
      if (refresh_diag) {
        const V4 dg = a * d * d + b * xyz;
        pi += dg;
        pre[j] += dg;
      }
    }
  }
  if (cur >= 0) sums[cur] += acc, pre[cur] += pi;
}

// Stage 3. The Jacobi preconditioner is the diagonal's reciprocal (the fourth lane 0 again), kept
// with the springs' diagonal, so that on the other steps only the anchored particles divide. The
// anchors add their terms to rhs, A Δv₀ and the diagonal; the fourth lane tells an anchored
// particle's sum (1) from a reciprocal (0), so a particle with two anchors divides once. Last,
// the filter: the constrained particles' rows are zero.
VSURG_SIMD_CLONES
void MassSpringModel::ImplicitPreconditioner(double h, bool refresh_diag) {
  const int n = static_cast<int>(x_.size());
  V4 *const dv = View(dv_), *const pre = View(precond_), *const diag = View(diag_),
            *const inv_diag = View(inv_diag_);
  V8* const sums = reinterpret_cast<V8*>(sums_.data());
  const V4 xyz{1.0, 1.0, 1.0, 0.0};
  const double h2 = h * h;
  if (refresh_diag) {
    for (int i = 0; i < n; ++i) {
      diag[i] = pre[i];
      inv_diag[i] = xyz / pre[i];
      pre[i] = inv_diag[i];
    }
    diag_age_ = 0, diag_h_ = h;
  }
  ++diag_age_;
  for (const Anchor& a : anchors_) pre[a.i] = diag[a.i];
  for (const Anchor& a : anchors_) {
    const double d = h * a.c + h2 * a.k;
    const Vec3 f = h * (a.k * (a.target - x_[a.i]) - a.c * v_[a.i]) - h2 * a.k * v_[a.i];
    const V4 ddv = d * dv[a.i];
    sums[a.i] += V8{f.x(), f.y(), f.z(), 0.0, -ddv[0], -ddv[1], -ddv[2], 0.0};
    pre[a.i] += V4{d, d, d, 0.0};
  }
  for (const Anchor& a : anchors_)
    if (pre[a.i][3] != 0.0) pre[a.i] = xyz / pre[a.i];
  for (int i : constrained_) sums[i] = V8{}, pre[i] = V4{};
}

// q = A p, returning pᵀA p, in one pass, the constrained particles' rows filtered to zero. pᵀA p
// is summed per term: m |p|² per particle, eᵀB_s e = a (l̂·e)² + b |e|² per spring, (h c + h² k)
// |p|² per anchor (p is 0 on the constrained particles, so the filter leaves it unchanged). With
// `next` (every iteration after the first) the first loop also makes p the next search direction,
// p = z + β p with z = pre r (z is never stored: pre and r are read anyway).
VSURG_SIMD_CLONES
double MassSpringModel::ImplicitProduct(double h, bool next, double beta) {
  const int n = static_cast<int>(x_.size());
  V4 *const u = View(p_), *const y = View(q_), *const pre = View(precond_), *const res = View(r_),
            *const dirs = View(dirs_);
  const SpringEnds* const ends = ends_.data();
  const double *const coef_a = coef_a_.data(), *const coef_b = coef_b_.data(),
                      *const mass = sys_.masses.data();
  const double h2 = h * h;
  const size_t ns = ends_.size();
  V4 uu{};
  if (next) {
    for (int i = 0; i < n; ++i) {
      const V4 ui = pre[i] * res[i] + beta * u[i];
      u[i] = ui;
      const V4 yi = mass[i] * ui;
      y[i] = yi;
      uu += yi * ui;
    }
  } else {
    for (int i = 0; i < n; ++i) {
      y[i] = mass[i] * u[i];
      uu += y[i] * u[i];
    }
  }
  int at = -1;
  V4 sum{}, ui{}, et{};  // running sum for particle `at`, its u, and the springs' eᵀB_s e
  for (size_t s = 0; s < ns; ++s) {
    const int j = ends[s].j;
    if (ends[s].i != at) {
      if (at >= 0) y[at] += sum;
      at = ends[s].i, sum = V4{}, ui = u[at];
    }
    const V4& d = dirs[s];
    const V4 e = ui - u[j];
    V4 de;  // l̂·e in every lane
    simd::Dots(de, e, d);
    const V4 t = (coef_a[s] * de) * d + coef_b[s] * e;
    sum += t;
    et += e * t;
    y[j] -= t;
  }
  if (at >= 0) y[at] += sum;
  for (const Anchor& a : anchors_) {
    const V4 t = (h * a.c + h2 * a.k) * u[a.i];
    y[a.i] += t;
    uu += t * u[a.i];
  }
  for (int i : constrained_) y[i] = V4{};
  return simd::Sum(uu + et);
}

// Stage 4, preconditioned conjugate gradient from the guess: the residual rhs − A Δv₀ is the
// pairs' sum. The dot products are summed lane by lane and the lanes added at the end. Stops at
// the relative tolerance, at the iteration limit, or when the search direction vanishes (or the
// system lost definiteness). Returns the iterations taken.
VSURG_SIMD_CLONES
int MassSpringModel::ImplicitSolve(double h) {
  const int n = static_cast<int>(x_.size());
  V4 *const dv = View(dv_), *const res = View(r_), *const p = View(p_), *const q = View(q_),
            *const pre = View(precond_);
  const V8* const sums = reinterpret_cast<const V8*>(sums_.data());
  double rhs_norm2 = 0, rz = 0, r2 = 0;
  {
    V4 rhs2{}, rz4{}, r24{};
    for (int i = 0; i < n; ++i) {
      const V8& pair = sums[i];
      const V4 rhs = __builtin_shufflevector(pair, pair, 0, 1, 2, 3);
      const V4 r = rhs + __builtin_shufflevector(pair, pair, 4, 5, 6, 7);
      res[i] = r;
      p[i] = pre[i] * r;
      rhs2 += rhs * rhs;
      rz4 += r * p[i];
      r24 += r * r;
    }
    rhs_norm2 = simd::Sum(rhs2), rz = simd::Sum(rz4), r2 = simd::Sum(r24);
  }
  const double tol2 = params_.cg_tolerance * params_.cg_tolerance * rhs_norm2;
  int it = 0;
  double beta = 0;
  const double rz_floor = 2 * params_.cg_energy_floor;  // rz is twice the error's energy
  for (; it < params_.cg_max_iterations && r2 > tol2 && rz > rz_floor; ++it) {
    const double pq = ImplicitProduct(h, it > 0, beta);
    if (!(pq > 0)) break;
    const double step = rz / pq;
    V4 rz4{}, r24{};
    for (int i = 0; i < n; ++i) {
      dv[i] += step * p[i];
      const V4 r = res[i] - step * q[i];
      res[i] = r;
      rz4 += r * (pre[i] * r);
      r24 += r * r;
    }
    const double rz_new = simd::Sum(rz4);
    r2 = simd::Sum(r24);
    beta = rz_new / rz;
    rz = rz_new;
  }
  return it;
}

// Stage 5, the update v₁ = v₀ + Δv, x₁ = x₀ + h v₁ of the free particles, with CheckFinite's test
// in the same pass: every particle within divergence_distance of rest (false for NaN) and every
// velocity finite (v·0 is 0 unless v has an infinity or a NaN). The pass leaves x and v in the
// four-lane copies too (pos_ and state_'s v₀), which the next step's guess reads for the free
// particles instead of converting x_ and v_ again (lanes_, cleared by whatever else writes x_ or
// v_: a reset, the other integrators, a change of role).
VSURG_SIMD_CLONES
bool MassSpringModel::ImplicitUpdate(double h) {
  const int n = static_cast<int>(x_.size());
  V4 *const dv = View(dv_), *const pos = View(pos_);
  V4* const state_v = reinterpret_cast<V4*>(state_.data());
  const double limit2 = params_.divergence_distance * params_.divergence_distance;
  const Vec3* const rest_x = sys_.rest_positions.data();
  bool near = true;
  V4 zero{};
  for (int i = 0; i < n; ++i) {
    V4 xi, vi;
    if (role_[i] == Role::kFree) {
      vi = state_v[2 * i] + dv[i];  // v₀, as the guess read it
      xi = pos[i] + h * vi;
      v_[i] = Vec3(vi[0], vi[1], vi[2]);
      x_[i] = Vec3(xi[0], xi[1], xi[2]);
    } else {
      vi = V4{v_[i].x(), v_[i].y(), v_[i].z(), 0.0};
      xi = V4{x_[i].x(), x_[i].y(), x_[i].z(), 0.0};
    }
    state_v[2 * i] = vi, pos[i] = xi;
    const V4 r = xi - V4{rest_x[i].x(), rest_x[i].y(), rest_x[i].z(), 0.0};
    near &= Dot(r, r) <= limit2;
    zero += 0.0 * vi;
  }
  lanes_ = true;
  return near && zero[0] == 0.0 && zero[1] == 0.0 && zero[2] == 0.0;
}

}  // namespace vsurg::tissue
