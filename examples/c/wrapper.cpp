// The C++ wrapper (capi/include/graybox.hpp): a model as an RAII object whose failures are
// exceptions. Usage: wrapper MODEL.gbx — one step from rest, ten with their z, then a load that
// must fail.
#include <cstdio>
#include <vector>

#include "graybox.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s MODEL.gbx\n", argv[0]);
    return 2;
  }
  graybox::Model model(argv[1]);
  const size_t nx = model.nq() + model.nv();
  std::vector<double> x = model.neutral(), u(model.m(), 0.0), next(nx);
  model.predict(x.data(), u.data(), 1, next.data());
  std::printf("one step of %g s from rest: qdot[0] = %.6g\n", model.dt(), next[model.nq()]);
  std::vector<double> xs(11 * nx), us(10 * model.m(), 0.0), z(10);
  model.rollout_z(x.data(), us.data(), 10, xs.data(), z.data());
  std::printf("ten steps from rest: z at the last = %.3g\n", z[9]);
  graybox::Workspace ws = model.workspace(1);
  std::vector<double> again(11 * nx);
  model.rollout(ws, x.data(), us.data(), 10, again.data());
  std::printf("the same in a workspace: %s\n", again == xs ? "equal" : "different");
  try {
    graybox::Model missing("no/such/model.gbx");
  } catch (const graybox::Error& e) {
    std::printf("status %d: %s\n", static_cast<int>(e.status()), e.what());
    return 0;
  }
  return 1;
}
