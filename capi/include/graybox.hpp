// graybox.hpp: a C++17 wrapper of graybox.h (written by hand, header-only). A Model owns its
// handle (RAII: freed when the Model goes), is movable, not copyable, and may be shared by
// reference across threads like the handle; a failed call throws graybox::Error with the
// status and the library's message.
#ifndef GRAYBOX_HPP
#define GRAYBOX_HPP

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "graybox.h"

namespace graybox {

class Error : public std::runtime_error {
 public:
  Error(GbxStatus status, const char* message) : std::runtime_error(message), status_(status) {}
  GbxStatus status() const { return status_; }

 private:
  GbxStatus status_;
};

inline void check(GbxStatus status) {
  if (status != GBX_STATUS_OK) throw Error(status, gbx_last_error());
}

// A caller-owned workspace (gbx_workspace_new): the scratch of one model's calls of up to
// max_batch states, for one thread at a time; the Model calls that take it allocate nothing.
class Workspace {
 public:
  Workspace(const GbxModel* model, size_t max_batch) {
    GbxWorkspace* w = nullptr;
    check(gbx_workspace_new(model, max_batch, &w));
    handle_.reset(w);
  }
  GbxWorkspace* get() const { return handle_.get(); }

 private:
  struct Free {
    void operator()(GbxWorkspace* w) const { gbx_workspace_free(w); }
  };
  std::unique_ptr<GbxWorkspace, Free> handle_;
};

class Model {
 public:
  explicit Model(const std::string& path) {
    GbxModel* m = nullptr;
    check(gbx_model_load(path.c_str(), &m));
    handle_.reset(m);
  }
  Model(const uint8_t* data, size_t len) {
    GbxModel* m = nullptr;
    check(gbx_model_load_buffer(data, len, &m));
    handle_.reset(m);
  }

  // A state is [q, v]: nq configuration values, nv velocities.
  size_t nq() const { return gbx_model_nq(get()); }
  size_t nv() const { return gbx_model_nv(get()); }
  // Deprecated: nv() (equal to nq() and nv() for a model whose every joint is one number).
  size_t n() const { return gbx_model_nv(get()); }
  // The neutral state [q, v] (every coordinate 0, a rotation at (1, 0), at rest).
  std::vector<double> neutral() const {
    std::vector<double> x(nq() + nv());
    check(gbx_model_neutral(get(), x.data()));
    return x;
  }
  size_t m() const { return gbx_model_m(get()); }
  double dt() const { return gbx_model_dt(get()); }
  // Null when the file proved it is whole; else why it loaded without that proof (a file from
  // before graybox files carried a checksum), owned by the model.
  const char* warning() const { return gbx_model_warning(get()); }

  // Each call below stops when a non-null `cancel` turns nonzero (set by another thread or a
  // signal handler), throwing Error with GBX_STATUS_CANCELLED.

  // x [batch, nq + nv], u [batch, m] -> x_next [batch, nq + nv] (and v̇ [batch, nv] unless null).
  void predict(const double* x, const double* u, size_t batch, double* x_next,
               double* accel = nullptr, const int32_t* cancel = nullptr) const {
    check(gbx_predict_cancellable(get(), x, u, batch, x_next, accel, cancel));
  }
  // A [batch, 2nv, 2nv] and B [batch, 2nv, m] of the one-step map, in the tangent space.
  void linearize(const double* x, const double* u, size_t batch, double* a, double* b,
                 const int32_t* cancel = nullptr) const {
    check(gbx_linearize_cancellable(get(), x, u, batch, a, b, cancel));
  }
  // xs [steps + 1, nq + nv] from x0 [nq + nv] under u [steps, m].
  void rollout(const double* x0, const double* u, size_t steps, double* xs,
               const int32_t* cancel = nullptr) const {
    check(gbx_rollout_cancellable(get(), x0, u, steps, xs, cancel));
  }

  // The same calls that also write z, how far each row's state and input lie from the
  // training data (max |z-score| of q, qdot and u; above ~4, treat the outputs with doubt):
  // z [batch] for predict and linearize, z [steps] of (x_t, u_t) for rollout.
  void predict_z(const double* x, const double* u, size_t batch, double* x_next, double* z,
                 double* accel = nullptr, const int32_t* cancel = nullptr) const {
    check(gbx_predict_z_cancellable(get(), x, u, batch, x_next, accel, z, cancel));
  }
  void linearize_z(const double* x, const double* u, size_t batch, double* a, double* b,
                   double* z, const int32_t* cancel = nullptr) const {
    check(gbx_linearize_z_cancellable(get(), x, u, batch, a, b, z, cancel));
  }
  void rollout_z(const double* x0, const double* u, size_t steps, double* xs, double* z,
                 const int32_t* cancel = nullptr) const {
    check(gbx_rollout_z_cancellable(get(), x0, u, steps, xs, z, cancel));
  }

  // The calls in a workspace of the caller's (real-time loops: one per thread), every
  // option at once; `accel`, `z` and `cancel` may be null.
  Workspace workspace(size_t max_batch) const { return Workspace(get(), max_batch); }
  void predict(Workspace& ws, const double* x, const double* u, size_t batch, double* x_next,
               double* accel = nullptr, double* z = nullptr,
               const int32_t* cancel = nullptr) const {
    check(gbx_predict_ws(get(), ws.get(), x, u, batch, x_next, accel, z, cancel));
  }
  void linearize(Workspace& ws, const double* x, const double* u, size_t batch, double* a,
                 double* b, double* z = nullptr, const int32_t* cancel = nullptr) const {
    check(gbx_linearize_ws(get(), ws.get(), x, u, batch, a, b, z, cancel));
  }
  void rollout(Workspace& ws, const double* x0, const double* u, size_t steps, double* xs,
               double* z = nullptr, const int32_t* cancel = nullptr) const {
    check(gbx_rollout_ws(get(), ws.get(), x0, u, steps, xs, z, cancel));
  }
  // The same at a step of `dt` seconds instead of the model's own (`dt()`): the dynamics are
  // continuous, so a model trained at one rate answers at the rate the caller runs at.
  void predict_dt(Workspace& ws, double dt, const double* x, const double* u, size_t batch,
                  double* x_next, double* accel = nullptr, double* z = nullptr,
                  const int32_t* cancel = nullptr) const {
    check(gbx_predict_dt_ws(get(), ws.get(), dt, x, u, batch, x_next, accel, z, cancel));
  }
  void rollout_dt(Workspace& ws, double dt, const double* x0, const double* u, size_t steps,
                  double* xs, double* z = nullptr, const int32_t* cancel = nullptr) const {
    check(gbx_rollout_dt_ws(get(), ws.get(), dt, x0, u, steps, xs, z, cancel));
  }

  // The generalized force tau [batch, nv] that produces accelerations qdd [batch, nv] at x
  // [batch, nq + nv]: a robot's feed-forward torque (allocates: not for a hard real-time loop).
  void inverse_dynamics(const double* x, const double* qdd, size_t batch, double* tau) const {
    check(gbx_inverse_dynamics(get(), x, qdd, batch, tau));
  }

  const GbxModel* get() const { return handle_.get(); }

 private:
  struct Free {
    void operator()(GbxModel* m) const { gbx_model_free(m); }
  };
  std::unique_ptr<GbxModel, Free> handle_;
};

}  // namespace graybox

#endif  // GRAYBOX_HPP
