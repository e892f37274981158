// Pinocchio through its C++ API beside graybox's Predict / Linearize of one state (see
// README.md in this directory; build with build.sh).
//
//   bench URDF [calls (default 20000)]
//
// Loads URDF (fixed base), draws 64 random states (q, v, tau uniform in [-1, 1], seed 0) and
// cycles through them; prints one JSON line per figure: mean / p50 / p99 µs per call, each
// call timed alone with std::chrono::steady_clock after calls/10 warm-up calls. Before the
// timings (untimed) the RK4 step's Jacobian is checked against central finite differences.
//
// Which machine code runs ("code" in every JSON line), chosen when compiling (build.sh
// builds both):
// - "header" (default): built without PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION, so all of
//   Pinocchio's algorithms are instantiated in this file and compiled with this build's
//   flags (-O3 -march=native); the library is used only to parse the URDF.
// - "library" (-DBENCH_USE_LIBRARY -DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION): arguments are
//   passed as Eigen::Ref<const VectorXd>, which selects the explicit instantiations compiled
//   into libpinocchio_default.so (generic x86-64; the code the Python binding runs).
#include <pinocchio/parsers/urdf.hpp>

#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

using Eigen::ArrayXd;
using Eigen::MatrixXd;
using Eigen::VectorXd;
using pinocchio::Data;
using pinocchio::Model;

namespace {

constexpr double kDt = 0.01;         // RK4 step, s
constexpr double kCoulombEps = 0.01; // friction * tanh(v / eps): graybox's smoothed Coulomb
constexpr int kStates = 64;

// Argument wrapper: see the header comment.
#ifdef BENCH_USE_LIBRARY
  #ifndef PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION
    #error "BENCH_USE_LIBRARY needs PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION"
  #endif
constexpr const char * kCode = "library";
inline Eigen::Ref<const VectorXd> arg(const VectorXd & x)
{
  return Eigen::Ref<const VectorXd>(x);
}
#else
  #ifdef PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION // would mix library and inlined code
    #error "header mode: build without PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION"
  #endif
constexpr const char * kCode = "header";
inline const VectorXd & arg(const VectorXd & x)
{
  return x;
}
#endif

// Keeps the optimiser from treating a result as dead.
inline void escape(const void * p)
{
  asm volatile("" : : "g"(p) : "memory");
}

// One RK4 step of x = (q, v) under tau = u - damping∘v - friction∘tanh(v/eps), and its
// Jacobian by the chain rule through the four stages. All workspace is allocated here, once.
class Rk4
{
public:
  explicit Rk4(const Model & model)
  : model_(model)
  , data_(model)
  , n_(static_cast<int>(model.nv))
  , damping_(model.damping)
  , friction_(model.upperDryFrictionLimit) // what the deprecated model.friction refers to
  , tau_(n_)
  , th_(n_)
  , dtau_(n_)
  , qs_(n_)
  , minv_(n_, n_)
  , av_(n_, n_)
  , x_(2 * n_, 3 * n_)
  , dk_(2 * n_, 3 * n_)
  {
    for (int s = 0; s < 4; ++s)
    {
      kv_[s].resize(n_);
      vs_[s].resize(n_);
    }
  }

  Data & data()
  {
    return data_;
  }

  // x' = RK4(q, v; u).  qn, vn must not alias q, v.
  void step(
    const VectorXd & q, const VectorXd & v, const VectorXd & u, VectorXd & qn, VectorXd & vn)
  {
    static constexpr double c[3] = {0.5, 0.5, 1.0};
    vs_[0] = v;
    kv_[0] = accel(q, vs_[0], u);
    for (int s = 1; s < 4; ++s)
    {
      qs_ = q + (c[s - 1] * kDt) * vs_[s - 1]; // stage s's q: k_{s-1}'s q part is v_{s-1}
      vs_[s] = v + (c[s - 1] * kDt) * kv_[s - 1];
      kv_[s] = accel(qs_, vs_[s], u);
    }
    combine(q, v, qn, vn);
  }

  // J = ∂(q', v')/∂(q, v, u), 2n × 3n, and the step itself (qn, vn).
  void jacobian(
    const VectorXd & q,
    const VectorXd & v,
    const VectorXd & u,
    MatrixXd & J,
    VectorXd & qn,
    VectorXd & vn)
  {
    static constexpr double c[3] = {0.5, 0.5, 1.0};
    static constexpr double w[4] = {1.0, 2.0, 2.0, 1.0};
    const int n = n_;
    // J accumulates [I 0] + dt/6 Σ w_s ∂k_s; x_ is ∂(q_s, v_s)/∂(q, v, u) of the stage's state.
    J.setZero();
    J.diagonal().setOnes();
    vs_[0] = v;
    for (int s = 0; s < 4; ++s)
    {
      stage_derivatives(s == 0 ? q : qs_, vs_[s], u); // fills av_, minv_, data_.ddq*
      kv_[s] = data_.ddq; // computeABADerivatives runs ABA: its ddq is this stage's q̈
      // ∂k_s = [∂v_s ; ∂q̈_s] with ∂q̈_s = Aq ∂q_s + Av ∂v_s + Minv ∂u.
      auto dkq = dk_.topRows(n);
      auto dkv = dk_.bottomRows(n);
      if (s == 0)
      { // ∂(q, v)/∂(q, v, u) = [I 0]: no products needed
        dkq.setZero();
        dkq.middleCols(n, n).setIdentity();
        dkv.leftCols(n) = data_.ddq_dq;
        dkv.middleCols(n, n) = av_;
      }
      else
      {
        dkq = x_.bottomRows(n);
        dkv.noalias() = data_.ddq_dq * x_.topRows(n);
        dkv.noalias() += av_ * x_.bottomRows(n);
      }
      if (s == 0)
        dkv.rightCols(n) = minv_;
      else
        dkv.rightCols(n) += minv_;
      J += (kDt / 6.0 * w[s]) * dk_;
      if (s < 3)
      {
        const double h = c[s] * kDt;
        x_ = h * dk_;
        x_.diagonal().array() += 1.0;
        qs_ = q + h * vs_[s];
        vs_[s + 1] = v + h * kv_[s];
      }
    }
    combine(q, v, qn, vn);
  }

private:
  void joint_torque(const VectorXd & v, const VectorXd & u)
  {
    th_ = (v.array() * (1.0 / kCoulombEps)).tanh();
    tau_ = u - damping_.cwiseProduct(v) - friction_.cwiseProduct(th_.matrix());
  }

  const VectorXd & accel(const VectorXd & q, const VectorXd & v, const VectorXd & u)
  {
    joint_torque(v, u);
    return pinocchio::aba(model_, data_, arg(q), arg(v), arg(tau_));
  }

  // ∂q̈/∂q is data_.ddq_dq; ∂q̈/∂v = ddq_dv + Minv ∂τ/∂v into av_; ∂q̈/∂u = Minv into minv_.
  void stage_derivatives(const VectorXd & q, const VectorXd & v, const VectorXd & u)
  {
    joint_torque(v, u);
    pinocchio::computeABADerivatives(model_, data_, arg(q), arg(v), arg(tau_));
    // Only the upper triangle of data.Minv is filled.
    minv_.triangularView<Eigen::Upper>() = data_.Minv;
    minv_.triangularView<Eigen::StrictlyLower>() = data_.Minv.transpose();
    // ∂τ/∂v = −diag(damping + friction (1 − tanh²(v/eps)) / eps)
    dtau_ = damping_.array() + friction_.array() * (1.0 - th_.square()) * (1.0 / kCoulombEps);
    av_ = data_.ddq_dv;
    av_.noalias() -= minv_ * dtau_.matrix().asDiagonal();
  }

  void combine(const VectorXd & q, const VectorXd & v, VectorXd & qn, VectorXd & vn) const
  {
    qn = q + (kDt / 6.0) * (vs_[0] + 2.0 * vs_[1] + 2.0 * vs_[2] + vs_[3]);
    vn = v + (kDt / 6.0) * (kv_[0] + 2.0 * kv_[1] + 2.0 * kv_[2] + kv_[3]);
  }

  const Model & model_;
  Data data_;
  int n_;
  VectorXd damping_, friction_, tau_;
  ArrayXd th_, dtau_;
  VectorXd qs_, kv_[4], vs_[4];
  MatrixXd minv_, av_, x_, dk_;
};

struct States
{
  std::vector<VectorXd> q, v, tau;
};

States draw_states(int n)
{
  std::mt19937_64 rng(0);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  States st;
  for (auto * vec : {&st.q, &st.v, &st.tau})
  {
    vec->resize(kStates);
    for (auto & x : *vec)
    {
      x.resize(n);
      for (int i = 0; i < n; ++i)
        x[i] = uni(rng);
    }
  }
  return st;
}

std::string json_string(const std::string & s)
{
  std::string out = "\"";
  for (char ch : s)
  {
    if (ch == '"' || ch == '\\')
      out += '\\';
    out += ch;
  }
  return out + "\"";
}

struct Out
{
  std::string robot; // already JSON-quoted
  int n;
  const char * code;
};

template<class F>
void time_calls(const char * name, const Out & out, int calls, F && f)
{
  using clock = std::chrono::steady_clock;
  std::vector<double> us(static_cast<size_t>(calls));
  for (int i = 0; i < calls / 10; ++i)
    f(i % kStates);
  for (int i = 0; i < calls; ++i)
  {
    const auto t0 = clock::now();
    f(i % kStates);
    const auto t1 = clock::now();
    us[static_cast<size_t>(i)] = std::chrono::duration<double, std::micro>(t1 - t0).count();
  }
  double sum = 0.0;
  for (double x : us)
    sum += x;
  std::sort(us.begin(), us.end());
  auto rank = [&](double p) { // nearest rank
    size_t k = static_cast<size_t>(std::ceil(p * static_cast<double>(calls)));
    return us[std::min(std::max<size_t>(k, 1), us.size()) - 1];
  };
  std::printf(
    "{\"bench\":\"%s\",\"robot\":%s,\"n\":%d,\"calls\":%d,\"mean_us\":%.4f,\"p50_us\":%.4f,"
    "\"p99_us\":%.4f,\"pinocchio\":\"%s\",\"code\":\"%s\"}\n",
    name, out.robot.c_str(), out.n, calls, sum / calls, rank(0.50), rank(0.99), PINOCCHIO_VERSION,
    out.code);
  std::fflush(stdout);
}

// The Jacobian against central differences of step (h = 1e-6) at the first 4 states.
bool check_jacobian(Rk4 & rk, const States & st, int n, const Out & out)
{
  const double h = 1e-6;
  MatrixXd J(2 * n, 3 * n), fd(2 * n, 3 * n);
  VectorXd qn(n), vn(n), qj(n), vj(n), qp(n), vp(n), qm(n), vm(n);
  double max_diff = 0.0, max_fd = 0.0, max_step_diff = 0.0;
  bool ok = true;
  for (int i = 0; i < 4; ++i)
  {
    VectorXd z(3 * n);
    z << st.q[i], st.v[i], st.tau[i];
    rk.jacobian(st.q[i], st.v[i], st.tau[i], J, qj, vj);
    rk.step(st.q[i], st.v[i], st.tau[i], qn, vn);
    max_step_diff = std::max({max_step_diff, (qj - qn).cwiseAbs().maxCoeff(),
                              (vj - vn).cwiseAbs().maxCoeff()});
    for (int k = 0; k < 3 * n; ++k)
    {
      VectorXd zp = z, zm = z;
      zp[k] += h;
      zm[k] -= h;
      rk.step(zp.head(n), zp.segment(n, n), zp.tail(n), qp, vp);
      rk.step(zm.head(n), zm.segment(n, n), zm.tail(n), qm, vm);
      fd.col(k) << (qp - qm) / (2 * h), (vp - vm) / (2 * h);
    }
    const double d = (J - fd).cwiseAbs().maxCoeff(), m = fd.cwiseAbs().maxCoeff();
    ok = ok && d < 1e-6 * std::max(1.0, m) && max_step_diff < 1e-9;
    max_diff = std::max(max_diff, d);
    max_fd = std::max(max_fd, m);
  }
  std::printf(
    "{\"bench\":\"pinocchio_cpp_jacobian_check\",\"robot\":%s,\"n\":%d,\"states\":4,"
    "\"max_abs_diff\":%.3e,\"max_abs_fd\":%.3e,\"max_step_diff\":%.3e,\"ok\":%s,\"code\":\"%s\"}\n",
    out.robot.c_str(), n, max_diff, max_fd, max_step_diff, ok ? "true" : "false", out.code);
  std::fflush(stdout);
  return ok;
}

int run(const Model & model, int calls)
{
  const int n = static_cast<int>(model.nv);
  const Out out{json_string(model.name), n, kCode};
  const States st = draw_states(n);
  Rk4 rk(model);
  if (!check_jacobian(rk, st, n, out))
    return 1;

  Data & data = rk.data();
  VectorXd qn(n), vn(n);
  MatrixXd J(2 * n, 3 * n);
  time_calls("pinocchio_cpp_aba", out, calls, [&](int i) {
    pinocchio::aba(model, data, arg(st.q[i]), arg(st.v[i]), arg(st.tau[i]));
    escape(data.ddq.data());
  });
  time_calls("pinocchio_cpp_rnea", out, calls, [&](int i) {
    // the torques drawn serve as accelerations
    pinocchio::rnea(model, data, arg(st.q[i]), arg(st.v[i]), arg(st.tau[i]));
    escape(data.tau.data());
  });
  time_calls("pinocchio_cpp_crba", out, calls, [&](int i) {
    pinocchio::crba(model, data, arg(st.q[i]));
    escape(data.M.data());
  });
  time_calls("pinocchio_cpp_aba_derivatives", out, calls, [&](int i) {
    pinocchio::computeABADerivatives(
      model, data, arg(st.q[i]), arg(st.v[i]), arg(st.tau[i]));
    escape(data.ddq_dq.data());
  });
  time_calls("pinocchio_cpp_rk4_step", out, calls, [&](int i) {
    rk.step(st.q[i], st.v[i], st.tau[i], qn, vn);
    escape(qn.data());
    escape(vn.data());
  });
  time_calls("pinocchio_cpp_rk4_jacobian", out, calls, [&](int i) {
    rk.jacobian(st.q[i], st.v[i], st.tau[i], J, qn, vn);
    escape(J.data());
  });
  return 0;
}

} // namespace

int main(int argc, char ** argv)
{
  if (argc < 2 || argc > 3)
  {
    std::fprintf(stderr, "usage: %s URDF [calls (default 20000)]\n", argv[0]);
    return 2;
  }
  const int calls = argc > 2 ? std::atoi(argv[2]) : 20000;
  if (calls < 1)
  {
    std::fprintf(stderr, "calls must be a positive integer\n");
    return 2;
  }
  Model model;
  pinocchio::urdf::buildModel(argv[1], model); // fixed base
  if (model.nq != model.nv)
  {
    std::fprintf(stderr, "nq != nv (continuous joints?): not supported\n");
    return 2;
  }
  return run(model, calls);
}
