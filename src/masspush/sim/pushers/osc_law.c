// The arm's operational-space control loop in C: masspush.sim.pushers.arm's velocity
// phase, hold and retraction, one MuJoCo step after another, without returning to Python.
//
// The law is the one of arm.py's ArmPusher._torque / _control (the reference, kept and used
// where this library cannot be built), step for step and in the same order of operations:
//   tau = J^T (J M^-1 J^T + eps I)^-1 xdd,  xdd = kp [pos_err; rot_err] + kd (v_des - v),
// scaled uniformly into the torque limits left after gravity compensation.
// tests/sim/pushers/test_osc_compiled.py holds the two to equal rest poses (1e-9).
//
// Loaded with ctypes (masspush.sim.pushers.compiled); MjModel and MjData are passed by the
// addresses the MuJoCo bindings expose. No Python API is used.

#include <math.h>
#include <string.h>

#include <mujoco/mujoco.h>

#define NDOF 6
#define PI 3.141592653589793  // numpy.pi

typedef struct {
  int dof0;                      // the arm's first dof; its 6 dofs are consecutive
  int act[NDOF];                 // actuator ids
  int site;                      // tip site
  int ee;                        // end-effector geom
  const unsigned char* is_arm;   // (ngeom) the arm's geoms other than the end-effector
  const unsigned char* is_chain; // (ngeom) the chain's geoms
  double torque_limit[NDOF];
  double kp, kd, task_damping;
  double* jac;                   // (6, nv) scratch
  double* minv_jt;               // (6, nv) scratch
} Arm;

typedef struct {
  double x_des[3];
  double r_des[9];               // row-major 3x3
  double v_des[6];
  double free_axis[3];
  int use_free_axis;
} Target;

// x_R_des (-) x_R as arm.py's osc.rotation_error: the rotation vector turning r into r_des.
static void rotation_error(const double* r_des, const double* r, double* out) {
  double err[9];
  for (int i = 0; i < 3; i++) {
    for (int j = 0; j < 3; j++) {
      // err = r_des @ r.T
      err[3 * i + j] = r_des[3 * i] * r[3 * j] + r_des[3 * i + 1] * r[3 * j + 1] +
                       r_des[3 * i + 2] * r[3 * j + 2];
    }
  }
  double a = err[0], b = err[1], c = err[2], d = err[3], e = err[4], f = err[5];
  double g = err[6], h = err[7], i = err[8];
  double w = sqrt(fmax(0.0, 1.0 + a + e + i)) / 2.0;
  double vx = h - f, vy = c - g, vz = d - b;
  if (w > 1e-6) {
    vx = vx / (4.0 * w);
    vy = vy / (4.0 * w);
    vz = vz / (4.0 * w);
  } else {  // a half-turn: the axis from the diagonal
    double diag[3] = {a, e, i}, best = -1.0;
    int k = 0;
    for (int j = 0; j < 3; j++) {
      double v = sqrt(fmax((diag[j] + 1.0) / 2.0, 0.0));
      if (v > best) {
        best = v;
        k = j;
      }
    }
    double axis[3] = {err[k], err[3 + k], err[6 + k]};
    axis[k] += 1.0;
    double n = sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
    for (int j = 0; j < 3; j++) out[j] = PI * axis[j] / n;
    return;
  }
  double s = sqrt(vx * vx + vy * vy + vz * vz);
  if (s < 1e-12) {
    out[0] = out[1] = out[2] = 0.0;
    return;
  }
  double scale = 2.0 * atan2(s, w) / s;
  out[0] = vx * scale;
  out[1] = vy * scale;
  out[2] = vz * scale;
}

// The law, the limits and the contact check, between mj_step1 and mj_step2 (or in MuJoCo's
// control callback, the same point of mj_step): sets ctrl, the tip's velocity and the
// contact flags.
static void control_law(const mjModel* m, mjData* d, const Arm* arm, const Target* t,
                        double* tip_velocity, int* touching, int* arm_touch) {
  int nv = m->nv, o = arm->dof0;
  double* jac_full = arm->jac;
  mj_jacSite(m, d, jac_full, jac_full + 3 * nv, arm->site);
  double jac[NDOF][NDOF];
  for (int r = 0; r < NDOF; r++)
    for (int k = 0; k < NDOF; k++) jac[r][k] = jac_full[r * nv + o + k];
  for (int r = 0; r < NDOF; r++) {
    double v = 0.0;
    for (int k = 0; k < NDOF; k++) v += jac[r][k] * d->qvel[o + k];
    tip_velocity[r] = v;
  }
  mj_solveM(m, d, arm->minv_jt, jac_full, NDOF);
  double inv_lambda[NDOF * NDOF];
  for (int r = 0; r < NDOF; r++) {
    for (int c = 0; c < NDOF; c++) {
      double v = 0.0;
      for (int k = 0; k < NDOF; k++) v += jac[r][k] * arm->minv_jt[c * nv + o + k];
      inv_lambda[r * NDOF + c] = v;
    }
    inv_lambda[r * NDOF + r] += arm->task_damping;
  }
  const double* xpos = d->site_xpos + 3 * arm->site;
  double pos_err[3];
  for (int j = 0; j < 3; j++) pos_err[j] = t->x_des[j] - xpos[j];
  if (t->use_free_axis) {
    double along = pos_err[0] * t->free_axis[0] + pos_err[1] * t->free_axis[1] +
                   pos_err[2] * t->free_axis[2];
    for (int j = 0; j < 3; j++) pos_err[j] = pos_err[j] - along * t->free_axis[j];
  }
  double rot_err[3];
  rotation_error(t->r_des, d->site_xmat + 9 * arm->site, rot_err);
  double xdd[NDOF];
  for (int j = 0; j < 3; j++) {
    xdd[j] = arm->kp * pos_err[j] + arm->kd * (t->v_des[j] - tip_velocity[j]);
    xdd[3 + j] = arm->kp * rot_err[j] + arm->kd * (t->v_des[3 + j] - tip_velocity[3 + j]);
  }
  mju_cholFactor(inv_lambda, NDOF, 0.0);
  double force[NDOF];
  mju_cholSolve(force, inv_lambda, xdd, NDOF);
  double tau[NDOF];
  for (int k = 0; k < NDOF; k++) {
    double v = 0.0;
    for (int r = 0; r < NDOF; r++) v += jac[r][k] * force[r];
    tau[k] = v;
  }
  // The limits: one common scale keeps the commanded direction (osc.scale_to_limits).
  double headroom[NDOF], scale = 1.0;
  int over = 0;
  for (int k = 0; k < NDOF; k++) {
    headroom[k] = fmax(arm->torque_limit[k] - fabs(d->qfrc_gravcomp[o + k]), 0.0);
    if (fabs(tau[k]) > headroom[k]) {
      double s = headroom[k] / fabs(tau[k]);
      if (!over || s < scale) scale = s;
      over = 1;
    }
  }
  for (int k = 0; k < NDOF; k++) d->ctrl[arm->act[k]] = over ? tau[k] * scale : tau[k];
  *touching = 0;
  *arm_touch = 0;
  for (int c = 0; c < d->ncon; c++) {
    int g0 = d->contact[c].geom[0], g1 = d->contact[c].geom[1];
    if (!(arm->is_chain[g0] || arm->is_chain[g1])) continue;
    if (g0 == arm->ee || g1 == arm->ee) *touching = 1;
    if (arm->is_arm[g0] || arm->is_arm[g1]) *arm_touch = 1;
  }
}

// One controlled step: mj_step1, the law, mj_step2, and the largest torque ratio.
static void control_step(const mjModel* m, mjData* d, const Arm* arm, const Target* t,
                         double* tip_velocity, int* touching, int* arm_touch,
                         double* max_ratio) {
  int o = arm->dof0;
  mj_step1(m, d);
  control_law(m, d, arm, t, tip_velocity, touching, arm_touch);
  mj_step2(m, d);
  double ratio = 0.0;
  for (int k = 0; k < NDOF; k++) {
    double r = fabs(d->qfrc_actuator[o + k]) / arm->torque_limit[k];
    if (r > ratio) ratio = r;
  }
  if (ratio > *max_ratio) *max_ratio = ratio;
}

// The velocity phase and the hold (arm.py, ArmPusher.deliver step 3). Writes the tip's
// speed along the push at each step into tip_speed (room for deadline + hold values) and
// returns 0, 1 (arm_contact) or 2 (unreachable); *steps the steps taken.
int masspush_velocity_phase(const mjModel* m, mjData* d, const Arm* arm, const Target* t,
                            int hold, int deadline, double* tip_speed, int* contact_step,
                            int* steps, double* max_ratio) {
  double v[NDOF];
  int touching, arm_touch, step = 0;
  *contact_step = -1;
  for (;;) {
    control_step(m, d, arm, t, v, &touching, &arm_touch, max_ratio);
    tip_speed[step] = v[0] * t->free_axis[0] + v[1] * t->free_axis[1] + v[2] * t->free_axis[2];
    if (arm_touch) {
      *steps = step + 1;
      return 1;
    }
    if (touching && *contact_step < 0) *contact_step = step;
    step++;
    if (*contact_step >= 0 && step >= *contact_step + hold) break;
    if (*contact_step < 0 && step >= deadline) {
      *steps = step;
      return 2;
    }
  }
  *steps = step;
  return 0;
}

// The retraction (step 4): `n` controlled steps towards the target at rest.
// Returns 0, or 1 where an arm part other than the tip touched the chain.
int masspush_retract(const mjModel* m, mjData* d, const Arm* arm, const Target* t, int n,
                     double* max_ratio) {
  double v[NDOF];
  int touching, arm_touch;
  for (int i = 0; i < n; i++) {
    control_step(m, d, arm, t, v, &touching, &arm_touch, max_ratio);
    if (arm_touch) return 1;
  }
  return 0;
}

// Lockstep: many chains, each with its arm, stepped together by MuJoCo's batch
// (masspush.sim.batch.ChainBatch). The velocity phase, the hold and the retraction above
// run as MuJoCo's control callback, one step per mj_step, each simulation's push and phase
// in its mjData.userdata (layout: masspush.sim.pushers.compiled.Userdata), so that every
// thread of the batch runs the law in C. The arm's ids and gains are the same in every
// chain's model (one scene layout), set once by masspush_set_arm.
enum {
  U_PHASE, U_STEP, U_CONTACT, U_HOLD, U_DEADLINE, U_RETRACT, U_SPEED,
  U_X, U_R = U_X + 3, U_V = U_R + 9, U_AXIS = U_V + 6, U_USE_AXIS = U_AXIS + 3, U_SIZE
};
enum { PH_OFF, PH_VELOCITY, PH_RETRACT, PH_DONE, PH_ARM_CONTACT, PH_UNREACHABLE };

static Arm lockstep_arm;
static int lockstep_ready = 0;

void masspush_set_arm(const Arm* arm) {
  lockstep_arm = *arm;
  lockstep_ready = 1;
}

int masspush_userdata_size(void) { return U_SIZE; }

// The control callback (mjcb_control): a no-op for a scene without the userdata or a
// simulation whose phase is off, so that it may stay installed for the whole process.
void masspush_control(const mjModel* m, mjData* d) {
  if (!lockstep_ready || m->nuserdata < U_SIZE) return;
  double* u = d->userdata;
  int phase = (int)u[U_PHASE];
  if (phase != PH_VELOCITY && phase != PH_RETRACT) return;
  Target t;
  memcpy(t.x_des, u + U_X, sizeof(t.x_des));
  memcpy(t.r_des, u + U_R, sizeof(t.r_des));
  memcpy(t.v_des, u + U_V, sizeof(t.v_des));
  memcpy(t.free_axis, u + U_AXIS, sizeof(t.free_axis));
  t.use_free_axis = (int)u[U_USE_AXIS];
  Arm arm = lockstep_arm;
  mj_markStack(d);
  arm.jac = mj_stackAllocNum(d, NDOF * m->nv);  // scratch of this simulation's thread
  arm.minv_jt = mj_stackAllocNum(d, NDOF * m->nv);
  double v[NDOF];
  int touching, arm_touch;
  control_law(m, d, &arm, &t, v, &touching, &arm_touch);
  mj_freeStack(d);
  if (phase == PH_RETRACT) {  // masspush_retract
    if (arm_touch) {
      u[U_PHASE] = PH_ARM_CONTACT;
    } else if (--u[U_RETRACT] <= 0) {
      u[U_PHASE] = PH_DONE;
    }
    return;
  }
  // masspush_velocity_phase, one pass of its loop
  double speed = v[0] * t.free_axis[0] + v[1] * t.free_axis[1] + v[2] * t.free_axis[2];
  if (speed > u[U_SPEED]) u[U_SPEED] = speed;
  if (arm_touch) {
    u[U_PHASE] = PH_ARM_CONTACT;
    return;
  }
  int step = (int)u[U_STEP], contact = (int)u[U_CONTACT];
  if (touching && contact < 0) u[U_CONTACT] = contact = step;
  u[U_STEP] = ++step;
  if (contact >= 0 && step >= contact + (int)u[U_HOLD]) {
    // The retraction's target: back towards the standoff, at rest, on every axis.
    for (int j = 0; j < NDOF; j++) u[U_V + j] = 0.0;
    for (int j = 0; j < 3; j++) u[U_AXIS + j] = 0.0;
    u[U_USE_AXIS] = 0.0;
    u[U_PHASE] = u[U_RETRACT] > 0 ? PH_RETRACT : PH_DONE;
  } else if (contact < 0 && step >= (int)u[U_DEADLINE]) {
    u[U_PHASE] = PH_UNREACHABLE;
  }
}

// The ABI this file was built for, checked by the loader against the running MuJoCo.
int masspush_mujoco_version(void) { return mjVERSION_HEADER; }
