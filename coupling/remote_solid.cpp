#include "coupling/remote_solid.hpp"

#include <algorithm>
#include <cstring>
#include <stdexcept>

namespace cellfsi::coupling {

namespace {

constexpr int kHeaderTag = 7101, kDataTag = 7102;

void check(int err, const char* what) {
  if (err != MPI_SUCCESS) throw std::runtime_error(std::string("MPI error in ") + what);
}

std::vector<double> encode(const std::string& s) { return std::vector<double>(s.begin(), s.end()); }
std::string decode(const std::vector<double>& d) {
  std::string s;
  for (double c : d) s.push_back(static_cast<char>(c));
  return s;
}

// The messages' layouts: doubles per item, the same on the fluid side (RemoteSolid) and the solid side
// (serve_solids), which pack and unpack through the functions below.
constexpr std::size_t kVecSize = 3;                       // a Vec3, or a Param
constexpr std::size_t kMatSize = 9;                       // a Mat3, row by row
constexpr std::size_t kSampleSize = kVecSize + kMatSize;  // VelocitySample: v, grad_v
// QuadratureData: x, weight, stress, beta, shear_modulus, force, area, has_tangent, and, when the request
// asked for the tangent, its upper triangle (kQuadratureSize doubles per point; kQuadratureTangent without
// it).
constexpr std::size_t kTangentSize = 21;
constexpr std::size_t kQuadratureWeight = kVecSize, kQuadratureStress = kQuadratureWeight + 1,
                      kQuadratureBeta = kQuadratureStress + kMatSize, kQuadratureShear = kQuadratureBeta + 1,
                      kQuadratureForce = kQuadratureShear + 1, kQuadratureArea = kQuadratureForce + kVecSize,
                      kQuadratureHasTangent = kQuadratureArea + 1,
                      kQuadratureTangent = kQuadratureHasTangent + 1,
                      kQuadratureSize = kQuadratureTangent + kTangentSize;

void put(std::vector<double>& out, const solid::Vec3& v) {
  out.insert(out.end(), v.data(), v.data() + kVecSize);
}
void put(std::vector<double>& out, const solid::Mat3& m) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out.push_back(m(r, c));
}
solid::Vec3 vec(const double* p) { return solid::Vec3(p[0], p[1], p[2]); }
solid::Mat3 mat(const double* p) {
  solid::Mat3 m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(r, c) = p[3 * r + c];
  return m;
}
std::vector<solid::Vec3> vecs(const std::vector<double>& d) {
  std::vector<solid::Vec3> v(d.size() / kVecSize);
  for (size_t i = 0; i < v.size(); ++i) v[i] = vec(&d[kVecSize * i]);
  return v;
}
std::vector<double> flat(const std::vector<solid::Vec3>& v) {
  std::vector<double> d;
  d.reserve(kVecSize * v.size());
  for (const auto& x : v) put(d, x);
  return d;
}

void put(std::vector<double>& out, const solid::VelocitySample& s) { put(out, s.v), put(out, s.grad_v); }
std::vector<solid::VelocitySample> unpack_samples(const std::vector<double>& d) {
  std::vector<solid::VelocitySample> s(d.size() / kSampleSize);
  for (size_t i = 0; i < s.size(); ++i) {
    const double* p = &d[kSampleSize * i];
    s[i].v = vec(p);
    s[i].grad_v = mat(p + kVecSize);
  }
  return s;
}

void put(std::vector<double>& out, const solid::QuadratureData& q, bool with_tangent) {
  put(out, q.x);
  out.push_back(q.weight);
  put(out, q.stress);
  out.push_back(q.beta);
  out.push_back(q.shear_modulus);
  put(out, q.force);
  out.push_back(q.area);
  out.push_back(q.has_tangent ? 1 : 0);
  if (with_tangent) out.insert(out.end(), q.tangent.begin(), q.tangent.end());
}
std::vector<solid::QuadratureData> unpack_quadrature(const std::vector<double>& d, bool with_tangent) {
  const std::size_t size = with_tangent ? kQuadratureSize : kQuadratureTangent;
  std::vector<solid::QuadratureData> q(d.size() / size);
  for (size_t i = 0; i < q.size(); ++i) {
    const double* p = &d[size * i];
    q[i].x = vec(p);
    q[i].weight = p[kQuadratureWeight];
    q[i].stress = mat(p + kQuadratureStress);
    q[i].beta = p[kQuadratureBeta];
    q[i].shear_modulus = p[kQuadratureShear];
    q[i].force = vec(p + kQuadratureForce);
    q[i].area = p[kQuadratureArea];
    q[i].has_tangent = with_tangent && p[kQuadratureHasTangent] != 0;
    if (q[i].has_tangent)
      std::copy(p + kQuadratureTangent, p + kQuadratureTangent + kTangentSize, q[i].tangent.begin());
  }
  return q;
}

std::vector<double> flat(const std::vector<geometry::Param>& xi) {
  std::vector<double> d;
  d.reserve(kVecSize * xi.size());
  for (const auto& p : xi) d.insert(d.end(), p.begin(), p.end());
  return d;
}
std::vector<geometry::Param> unpack_params(const std::vector<double>& d) {
  std::vector<geometry::Param> xi(d.size() / kVecSize);
  for (size_t i = 0; i < xi.size(); ++i) xi[i] = {d[kVecSize * i], d[kVecSize * i + 1], d[kVecSize * i + 2]};
  return xi;
}

std::vector<solid::Mat3> unpack_mats(const std::vector<double>& d) {
  std::vector<solid::Mat3> m(d.size() / kMatSize);
  for (size_t i = 0; i < m.size(); ++i) m[i] = mat(&d[kMatSize * i]);
  return m;
}

}  // namespace

// ----------------------------------------------------------------------------------------------------
// Exchange

Exchange::Exchange(MPI_Comm inter, std::size_t mailbox_bytes) : inter_(inter) {
  int is_inter = 0;
  check(MPI_Comm_test_inter(inter, &is_inter), "MPI_Comm_test_inter");
  if (!is_inter) throw std::invalid_argument("Exchange: needs an intercommunicator");
  MPI_Comm_size(inter, &local_size_);
  MPI_Comm_remote_size(inter, &remote_size_);
  // The group whose smallest world rank is lower comes first in the merged communicator.
  int world = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &world);
  // On an intercommunicator an allreduce returns the other group's reduction: first the remote group's
  // minimum, then, reducing those, our own group's.
  int remote_min = 0, local_min = 0;
  MPI_Allreduce(&world, &remote_min, 1, MPI_INT, MPI_MIN, inter);
  MPI_Allreduce(&remote_min, &local_min, 1, MPI_INT, MPI_MIN, inter);
  low_ = local_min < remote_min;
  check(MPI_Intercomm_merge(inter, low_ ? 0 : 1, &merged_), "MPI_Intercomm_merge");
  check(MPI_Comm_split_type(merged_, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node_), "MPI_Comm_split_type");
  MPI_Group merged_group, node_group;
  MPI_Comm_group(merged_, &merged_group);
  MPI_Comm_group(node_, &node_group);
  std::vector<int> in_merged(remote_size_);
  for (int r = 0; r < remote_size_; ++r) in_merged[r] = low_ ? local_size_ + r : r;
  remote_node_rank_.assign(remote_size_, MPI_UNDEFINED);
  MPI_Group_translate_ranks(merged_group, remote_size_, in_merged.data(), node_group,
                            remote_node_rank_.data());
  MPI_Group_free(&merged_group);
  MPI_Group_free(&node_group);
  for (int& r : remote_node_rank_)
    if (r == MPI_UNDEFINED) r = -1;
  capacity_ = mailbox_bytes / sizeof(double);
  if (capacity_ > 0) {
    check(MPI_Win_allocate_shared(static_cast<MPI_Aint>(capacity_ * sizeof(double)), sizeof(double),
                                  MPI_INFO_NULL, node_, &mine_, &win_),
          "MPI_Win_allocate_shared");
    check(MPI_Win_lock_all(MPI_MODE_NOCHECK, win_), "MPI_Win_lock_all");
  }
}

Exchange::~Exchange() {
  if (win_ != MPI_WIN_NULL) {
    MPI_Win_unlock_all(win_);
    MPI_Win_free(&win_);
  }
  if (node_ != MPI_COMM_NULL) MPI_Comm_free(&node_);
  if (merged_ != MPI_COMM_NULL) MPI_Comm_free(&merged_);
}

bool Exchange::shared_with(int peer) const { return capacity_ > 0 && remote_node_rank_.at(peer) >= 0; }

void Exchange::send(int peer, int op, int body, const std::vector<double>& data) {
  const bool via_shared = shared_with(peer) && data.size() <= capacity_;
  std::int64_t header[4] = {op, body, static_cast<std::int64_t>(data.size()), via_shared ? 1 : 0};
  if (via_shared) {
    MPI_Aint size = 0;
    int unit = 0;
    double* box = nullptr;
    check(MPI_Win_shared_query(win_, remote_node_rank_[peer], &size, &unit, &box), "MPI_Win_shared_query");
    if (!data.empty()) std::memcpy(box, data.data(), data.size() * sizeof(double));
    MPI_Win_sync(win_);  // the copy is visible before the header arrives
    shared_bytes_ += data.size() * sizeof(double);
  }
  check(MPI_Send(header, 4, MPI_INT64_T, peer, kHeaderTag, inter_), "MPI_Send");
  if (!via_shared && !data.empty()) {
    check(MPI_Send(data.data(), static_cast<int>(data.size()), MPI_DOUBLE, peer, kDataTag, inter_),
          "MPI_Send");
    message_bytes_ += data.size() * sizeof(double);
  }
}

Exchange::Message Exchange::recv(int peer) {
  std::int64_t header[4];
  check(MPI_Recv(header, 4, MPI_INT64_T, peer, kHeaderTag, inter_, MPI_STATUS_IGNORE), "MPI_Recv");
  Message m;
  m.op = static_cast<int>(header[0]);
  m.body = static_cast<int>(header[1]);
  m.data.resize(static_cast<size_t>(header[2]));
  if (header[3]) {
    MPI_Win_sync(win_);
    if (!m.data.empty()) std::memcpy(m.data.data(), mine_, m.data.size() * sizeof(double));
  } else if (!m.data.empty()) {
    check(MPI_Recv(m.data.data(), static_cast<int>(m.data.size()), MPI_DOUBLE, peer, kDataTag, inter_,
                   MPI_STATUS_IGNORE),
          "MPI_Recv");
  }
  return m;
}

// ------------------------------------------------------------------------------------------------
// RemoteSolid

RemoteSolid::RemoteSolid(Exchange& exchange, MPI_Comm fluid_comm, int index, std::string name,
                         geometry::Patch reference, bool membrane)
    : ex_(exchange),
      comm_(fluid_comm),
      index_(index),
      owner_(body_owner(index, exchange.remote_size())),
      name_(std::move(name)),
      reference_(std::move(reference)),
      membrane_(membrane) {}

std::vector<double> RemoteSolid::call(SolidOp op, const std::vector<double>& data) const {
  int rank = 0;
  MPI_Comm_rank(comm_, &rank);
  std::vector<double> reply;
  long n = 0;
  int failed = 0;
  if (rank == 0) {
    ex_.send(owner_, static_cast<int>(op), index_, data);
    Exchange::Message m = ex_.recv(owner_);
    failed = m.op == static_cast<int>(SolidOp::error);
    reply = std::move(m.data);
    n = static_cast<long>(reply.size());
  }
  MPI_Bcast(&failed, 1, MPI_INT, 0, comm_);
  MPI_Bcast(&n, 1, MPI_LONG, 0, comm_);
  reply.resize(static_cast<size_t>(n));
  if (n > 0) MPI_Bcast(reply.data(), static_cast<int>(n), MPI_DOUBLE, 0, comm_);
  if (failed) throw std::runtime_error("body '" + name_ + "' (solid side): " + decode(reply));
  return reply;
}

void RemoteSolid::hello() {
  const std::vector<double> r = call(SolidOp::hello, {});
  if (r.size() != 3 || r[0] != reference_.n_control() || r[1] != dim() || (r[2] != 0) != membrane_)
    throw std::runtime_error(
        "body '" + name_ + "': the solid side built it differently (were both sides given the same scene?)");
}

void RemoteSolid::begin_step(const solid::TimeParameters& t) {
  call(SolidOp::begin_step, {t.dt, t.alpha_m, t.alpha_f, t.gamma, t.t_n});
}

std::vector<solid::Vec3> RemoteSolid::collocation_points() const {
  return vecs(call(SolidOp::collocation_points, {}));
}

double RemoteSolid::kinematic_update(const std::vector<solid::VelocitySample>& samples) {
  std::vector<double> d;
  d.reserve(kSampleSize * samples.size());
  for (const auto& s : samples) put(d, s);
  return call(SolidOp::kinematic_update, d).at(0);
}

std::vector<solid::QuadratureData> RemoteSolid::quadrature_data(double fluid_density,
                                                                bool with_tangent) const {
  return unpack_quadrature(call(SolidOp::quadrature_data, {fluid_density, with_tangent ? 1.0 : 0.0}),
                           with_tangent);
}

std::vector<solid::Vec3> RemoteSolid::interface_points() const {
  return vecs(call(SolidOp::interface_points, {}));
}

void RemoteSolid::end_step() { call(SolidOp::end_step, {}); }

void RemoteSolid::set_rate(const std::vector<solid::Vec3>& rate) { call(SolidOp::set_rate, flat(rate)); }

std::vector<double> RemoteSolid::state() const { return call(SolidOp::state, {}); }

void RemoteSolid::set_state(const std::vector<double>& state) { call(SolidOp::set_state, state); }

geometry::Patch RemoteSolid::current_patch() const {
  std::vector<geometry::Vec3> cps = vecs(call(SolidOp::current_patch, {}));
  return geometry::Patch(reference_.all_knots(), dim(), std::move(cps), reference_.weights(),
                         reference_.shifts());
}

std::vector<solid::Mat3> RemoteSolid::cauchy_stress(const std::vector<geometry::Param>& xi) const {
  return unpack_mats(call(SolidOp::cauchy_stress, flat(xi)));
}

// ------------------------------------------------------------------------------------------------ the server

void serve_solids(Exchange& ex, const std::vector<solid::SolidSolver*>& bodies) {
  for (;;) {
    Exchange::Message m = ex.recv(0);
    const auto op = static_cast<SolidOp>(m.op);
    if (op == SolidOp::shutdown) return;
    std::vector<double> out;
    try {
      if (m.body < 0 || m.body >= static_cast<int>(bodies.size()) || !bodies[m.body])
        throw std::runtime_error("no body " + std::to_string(m.body) + " on this solid rank");
      solid::SolidSolver& b = *bodies[m.body];
      const std::vector<double>& d = m.data;
      switch (op) {
        case SolidOp::hello:
          out = {static_cast<double>(b.reference_patch().n_control()), static_cast<double>(b.dim()),
                 b.is_membrane() ? 1.0 : 0.0};
          break;
        case SolidOp::begin_step: {
          solid::TimeParameters t;
          t.dt = d.at(0), t.alpha_m = d.at(1), t.alpha_f = d.at(2), t.gamma = d.at(3), t.t_n = d.at(4);
          b.begin_step(t);
          break;
        }
        case SolidOp::collocation_points:
          out = flat(b.collocation_points());
          break;
        case SolidOp::kinematic_update: {
          out = {b.kinematic_update(unpack_samples(d))};
          break;
        }
        case SolidOp::quadrature_data: {
          const bool with_tangent = d.at(1) != 0;
          for (const auto& q : b.quadrature_data(d.at(0), with_tangent)) put(out, q, with_tangent);
          break;
        }
        case SolidOp::interface_points:
          out = flat(b.interface_points());
          break;
        case SolidOp::end_step:
          b.end_step();
          break;
        case SolidOp::set_rate:
          b.set_rate(vecs(d));
          break;
        case SolidOp::current_patch:
          out = flat(b.current_patch().control_points());
          break;
        case SolidOp::state:
          out = b.state();
          break;
        case SolidOp::set_state:
          b.set_state(d);
          break;
        case SolidOp::cauchy_stress: {
          for (const auto& s : b.cauchy_stress(unpack_params(d))) put(out, s);
          break;
        }
        default:
          throw std::runtime_error("unknown request " + std::to_string(m.op));
      }
      ex.send(0, m.op, m.body, out);
    } catch (const std::exception& e) {
      ex.send(0, static_cast<int>(SolidOp::error), m.body, encode(e.what()));
    }
  }
}

void shutdown_solids(Exchange& ex, MPI_Comm fluid_comm) {
  int rank = 0;
  MPI_Comm_rank(fluid_comm, &rank);
  if (rank != 0) return;
  for (int r = 0; r < ex.remote_size(); ++r) ex.send(r, static_cast<int>(SolidOp::shutdown), -1, {});
}

}  // namespace cellfsi::coupling
