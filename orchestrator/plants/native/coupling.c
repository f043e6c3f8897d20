/*
 * The simulated excavator's step loop (orchestrator.plants.simulated_excavator's module
 * docstring), the one implementation: per communication step h from t_k
 *
 *   1. the cylinders' strokes -> joint angles, moment arms, tip and bucket angle
 *      (orchestrator.plants.arm_coupling: Hermite tables, forward kinematics) -> the Pile's
 *      inputs; the Pile steps;
 *   2. the arm's loads at t_k: gravity (links, payload), the soil force through the Jacobian,
 *      the velocity products, the mass matrix M(q) (orchestrator.plants.arm_dynamics); the
 *      servos sample every servo_every steps (their own sample time, the command held between
 *      samples); the load-sensing pump's law;
 *   3. the arm coupling: each cylinder FMU integrates its own diagonal inertia M_ii / r_i^2 (its
 *      mass_load input); the cross inertia sum_{j != i} M_ij qdd_j / r_i reaches it through
 *      F_ext. With state rollback (implicit = 1) the step is iterated until that force agrees
 *      with the joint accelerations the cylinders then produce over the step (mean over the
 *      step, from their end velocities), to `tolerance` rad/s^2 of joint acceleration: a
 *      Newton iteration on the three forces whose Jacobian is I + K, K_ij = M_ij s_j /
 *      (h r_i r_j) (i != j), with each cylinder's step mobility s_j = -d v_end / d F_ext from
 *      the secant of its last two iterates (h / (M_jj / r_j^2) before any); the FMUs are put
 *      back into their states at t_k between iterates. Without rollback (implicit = 0) the
 *      cross terms come from the planned joint accelerations (explicit; the scheme the
 *      substitution of an FMU that cannot roll back falls back to).
 *
 * Each FMU steps through a function pointer (fmus/fast_step's one-call step, or a callback into
 * Python for a component that converts its ports); a board names the FMU in a step and its t
 * for the step watchdog and a crash report (orchestrator.plants.native.board). Units: SI (m,
 * rad, N, kg, Pa, s).
 */
#include <math.h>
#include <stddef.h>

#define EXPORT __attribute__((visibility("default")))

typedef struct {
    const double *angle, *c1, *c2, *c3, *arm, *arm_slope; /* per interval (arm: per node) */
    double inv_dx;                                        /* intervals per metre of stroke */
    long intervals;
} Table;

typedef struct {
    long linear; /* 0: pressure-feedback servo (plant_models.servo), 1: linear servo */
    double kp, kf, keep, gain, mass, extend, retract, least, per_reserve_extend;
    double per_reserve_retract, metered[2], pull[2], p_tank, areas[2];
    long compensated;
    double per_velocity; /* linear servo: spool command per m/s */
    double filtered, last; /* the filter's state; has_last = 0: no sample yet */
    long has_last;
    double held;           /* the command held since the last sample */
    double design_load;    /* kg: the reflected inertia the design holds (0: no scheduling) */
} Servo;

typedef struct {
    /* buffers of the FMU components, role order (orchestrator.plants.master.Component) */
    const double *cylinder_out[3]; /* x, v, p_A, p_B, F, E_supply, E_throttling */
    double *cylinder_in[3];        /* u, F_ext, mass_load, p_pump, p_LS */
    const double *pile_out;        /* bucket_mass, F_y, F_z, removed, dumped, pile, surface */
    double *pile_in;               /* tip_y, tip_z, bucket_angle, dump */
    /* the stroke reference per step, (n, 3) each, and what the steps produce */
    const double *x_ref, *v_ref, *a_ref;
    double *rows;   /* (n, n_columns): the signal columns of simulated_excavator */
    double *joints; /* (n, 3) rad */
    long n, k, n_columns;
    Table table[3];
    double lengths[3], foot[2], weights[3], coms[3][2], masses[3], gravity;
    Servo servo[3];
    long supplied;              /* 1: the load-sensing pump feeds the sections */
    double full[3];             /* a section's flow at the full margin, m^3/s; < 0: off pump */
    double q_max, margin, ceiling, power; /* power: the power limit, W */
    long servo_every;           /* communication steps per servo sample */
    long implicit;              /* 1: iterate the arm coupling with rollback */
    long max_iterations;
    double tolerance;           /* rad/s^2 of joint acceleration */
    double force[3];            /* the last step's cross-inertia forces, N (the predictor) */
    double previous_force[3];   /* the step's before, N */
    double mobility[3];         /* s/kg: the cylinders' step mobilities (< 0: none yet) */
    double pose[30]; /* scratch: ArmCoupling.kinematics of this step */
} Coupling;

/* ArmCoupling._joint: angle, arm and d(arm)/d(angle) at a stroke. */
static void joint(const Table *table, double stroke, double *out) {
    double position = stroke * table->inv_dx, fraction, t, arm;
    long i;
    /* Python's int() truncates toward 0 before the clamp; clamped first here, as a cast of a
     * value beyond a long is undefined (non-finite strokes are refused before this). */
    if (!(position >= 1.0)) {
        i = 0;
    } else if (position >= (double)table->intervals) {
        i = table->intervals - 1;
    } else {
        i = (long)position;
    }
    fraction = position - (double)i;
    t = fraction < 0.0 ? 0.0 : (fraction > 1.0 ? 1.0 : fraction);
    arm = table->arm[i] + table->arm_slope[i] * t;
    out[0] = table->angle[i] + t * (table->c1[i] + t * (table->c2[i] + t * table->c3[i]));
    out[1] = arm;
    out[2] = table->arm_slope[i] * table->inv_dx * arm;
}

/* ArmCoupling.kinematics into c->pose, the same order. */
static void kinematics(Coupling *c, double x0, double x1, double x2) {
    double j0[3], j1[3], j2[3], *p = c->pose;
    double l1 = c->lengths[0], l2 = c->lengths[1], l3 = c->lengths[2];
    double foot_y = c->foot[0], foot_z = c->foot[1], phi2, phi3, c1, s1, c2, s2, c3, s3;
    double stick_y, stick_z, pin_y, pin_z, tip_y, tip_z, com1, com2, com3;
    double w1 = c->weights[0], w2 = c->weights[1], w3 = c->weights[2];
    joint(&c->table[0], x0, j0);
    joint(&c->table[1], x1, j1);
    joint(&c->table[2], x2, j2);
    phi2 = j0[0] + j1[0];
    phi3 = phi2 + j2[0];
    c1 = cos(j0[0]);
    s1 = sin(j0[0]);
    c2 = cos(phi2);
    s2 = sin(phi2);
    c3 = cos(phi3);
    s3 = sin(phi3);
    stick_y = foot_y - l1 * c1;
    stick_z = foot_z + l1 * s1;
    pin_y = stick_y - l2 * c2;
    pin_z = stick_z + l2 * s2;
    tip_y = pin_y - l3 * c3;
    tip_z = pin_z + l3 * s3;
    com1 = foot_y - c->coms[0][0] * c1 + c->coms[0][1] * s1;
    com2 = stick_y - c->coms[1][0] * c2 + c->coms[1][1] * s2;
    com3 = pin_y - c->coms[2][0] * c3 + c->coms[2][1] * s3;
    p[0] = j0[0], p[1] = j1[0], p[2] = j2[0], p[3] = tip_y, p[4] = tip_z, p[5] = phi3;
    p[6] = j0[1], p[7] = j1[1], p[8] = j2[1];
    p[9] = w1 * (foot_y - com1) + w2 * (foot_y - com2) + w3 * (foot_y - com3);
    p[10] = w2 * (stick_y - com2) + w3 * (stick_y - com3);
    p[11] = w3 * (pin_y - com3);
    p[12] = c->gravity * (foot_y - com3);
    p[13] = c->gravity * (stick_y - com3);
    p[14] = c->gravity * (pin_y - com3);
    p[15] = tip_y - foot_y, p[16] = tip_z - foot_z, p[17] = tip_y - stick_y;
    p[18] = tip_z - stick_z, p[19] = tip_y - pin_y, p[20] = tip_z - pin_z;
    p[21] = j0[2], p[22] = j1[2], p[23] = j2[2];
    p[24] = c1, p[25] = s1, p[26] = c2, p[27] = s2, p[28] = c3, p[29] = s3;
}

/* ArmInertia._at: M00, M11, M22, M01, M02, M12, h0, h1, h2 into out. */
static void inertia(const Coupling *c, double w0, double w1, double w2, double payload,
                    double *out) {
    const double *p = c->pose;
    double c1 = p[24], s1 = p[25], c2 = p[26], s2 = p[27], c3 = p[28], s3 = p[29];
    double m1 = c->masses[0], m2 = c->masses[1], m3 = c->masses[2] + payload;
    double l1 = c->lengths[0], l2 = c->lengths[1], l3 = c->lengths[2];
    double u1 = c->coms[0][0], v1 = c->coms[0][1], u2 = c->coms[1][0], v2 = c->coms[1][1];
    double u3 = c->coms[2][0], v3 = c->coms[2][1];
    double g1y = u1 * s1 + v1 * c1, g1z = u1 * c1 - v1 * s1;
    double g2y = u2 * s2 + v2 * c2, g2z = u2 * c2 - v2 * s2;
    double g3y = u3 * s3 + v3 * c3, g3z = u3 * c3 - v3 * s3;
    double a1y = l1 * s1, a1z = l1 * c1, a2y = l2 * s2, a2z = l2 * c2;
    double i1 = m1 * l1 * l1 / 12.0, i2 = m2 * l2 * l2 / 12.0, i3 = m3 * l3 * l3 / 12.0;
    double n11 = m1 * (g1y * g1y + g1z * g1z) + (m2 + m3) * (a1y * a1y + a1z * a1z) + i1;
    double n22 = m2 * (g2y * g2y + g2z * g2z) + m3 * (a2y * a2y + a2z * a2z) + i2;
    double n33 = m3 * (g3y * g3y + g3z * g3z) + i3;
    double n12 = m2 * (a1y * g2y + a1z * g2z) + m3 * (a1y * a2y + a1z * a2z);
    double n13 = m3 * (a1y * g3y + a1z * g3z);
    double n23 = m3 * (a2y * g3y + a2z * g3z);
    double w_1 = w0, w_2 = w0 + w1, w_3, k1, k2, k3;
    double h1y, h1z, h2y, h2z, h3y, h3z, b1y, b1z, b2y, b2z;
    double vp1y, vp1z, vp2y, vp2z, vp3y, vp3z, e1, e2, e3;
    w_3 = w_2 + w2;
    k1 = w_1 * w_1, k2 = w_2 * w_2, k3 = w_3 * w_3;
    h1y = u1 * c1 - v1 * s1, h1z = -u1 * s1 - v1 * c1;
    h2y = u2 * c2 - v2 * s2, h2z = -u2 * s2 - v2 * c2;
    h3y = u3 * c3 - v3 * s3, h3z = -u3 * s3 - v3 * c3;
    b1y = l1 * c1, b1z = -l1 * s1, b2y = l2 * c2, b2z = -l2 * s2;
    vp1y = k1 * h1y, vp1z = k1 * h1z;
    vp2y = k1 * b1y + k2 * h2y, vp2z = k1 * b1z + k2 * h2z;
    vp3y = k1 * b1y + k2 * b2y + k3 * h3y, vp3z = k1 * b1z + k2 * b2z + k3 * h3z;
    e1 = (m1 * (g1y * vp1y + g1z * vp1z) + m2 * (a1y * vp2y + a1z * vp2z)
          + m3 * (a1y * vp3y + a1z * vp3z));
    e2 = m2 * (g2y * vp2y + g2z * vp2z) + m3 * (a2y * vp3y + a2z * vp3z);
    e3 = m3 * (g3y * vp3y + g3z * vp3z);
    out[0] = n11 + n22 + n33 + 2.0 * (n12 + n13 + n23);
    out[1] = n22 + 2.0 * n23 + n33;
    out[2] = n33;
    out[3] = n12 + n13 + n22 + 2.0 * n23 + n33;
    out[4] = n13 + n23 + n33;
    out[5] = n23 + n33;
    out[6] = e1 + e2 + e3, out[7] = e2 + e3, out[8] = e3;
}

/* The servo's law (plant_models.servo.JointServo.command; LinearJointServo.command for the
 * linear servo): the spool command in [-1, 1]; advances the filter. */
static double command(Servo *s, double x_ref, double v_ref, double a_ref, double x, double force,
                      double load) {
    double excess, last, filtered, velocity, u, pulled, gain, reserve, candidate;
    double mass = s->mass, scale = 1.0, keep, high;
    if (s->linear) {
        u = (v_ref + s->kp * (x_ref - x)) * s->per_velocity;
        return u > 1.0 ? 1.0 : (u < -1.0 ? -1.0 : u);
    }
    if (s->design_load > 0.0 && load > s->design_load) { /* gain scheduling on the load */
        mass = s->mass - s->design_load + load;
        scale = sqrt(s->mass / mass);
    }
    excess = force - mass * a_ref;
    last = s->has_last ? s->last : excess;
    keep = s->keep, high = s->gain;
    if (scale < 1.0) { /* the high-pass corner follows the mode: w_f T / 2 scaled */
        const double corner = (1.0 - s->keep) / (1.0 + s->keep) * scale;
        keep = (1.0 - corner) / (1.0 + corner);
        high = 1.0 / (1.0 + corner);
    }
    filtered = keep * s->filtered + high * (excess - last);
    s->filtered = filtered;
    s->last = excess;
    s->has_last = 1;
    velocity = v_ref + scale * (s->kp * (x_ref - x) - s->kf * filtered);
    if (s->compensated) {
        if (velocity >= 0.0) {
            pulled = -force / s->areas[1] - s->p_tank;
            gain = s->metered[0];
            if (pulled > 0.0) {
                candidate = s->pull[0] * sqrt(pulled);
                gain = candidate > gain ? candidate : gain;
            }
        } else {
            pulled = force / s->areas[0] - s->p_tank;
            gain = s->metered[1];
            if (pulled > 0.0) {
                candidate = s->pull[1] * sqrt(pulled);
                gain = candidate > gain ? candidate : gain;
            }
        }
        u = velocity / gain;
    } else if (velocity >= 0.0) {
        reserve = s->extend - force;
        if (reserve < s->least) reserve = s->least;
        u = velocity / sqrt(reserve * s->per_reserve_extend);
    } else {
        reserve = force + s->retract;
        if (reserve < s->least) reserve = s->least;
        u = velocity / sqrt(reserve * s->per_reserve_retract);
    }
    return u > 1.0 ? 1.0 : (u < -1.0 ? -1.0 : u);
}

/* LoadSensingPump.law: p_pump, p_LS, sharing into out (flow, then power limited). */
static void supply(const Coupling *c, const double *u, const double *p_A, const double *p_B,
                   double *out) {
    double p_ls = 0.0, demand = 0.0, sharing;
    int i;
    for (i = 0; i < 3; i++) {
        if (c->full[i] < 0.0) continue;
        if (u[i] > 0.0) {
            demand += c->full[i] * (u[i] < 1.0 ? u[i] : 1.0);
            p_ls = p_A[i] > p_ls ? p_A[i] : p_ls;
        } else if (u[i] < 0.0) {
            demand -= c->full[i] * (u[i] > -1.0 ? u[i] : -1.0);
            p_ls = p_B[i] > p_ls ? p_B[i] : p_ls;
        }
    }
    p_ls = p_ls < c->ceiling ? p_ls : c->ceiling;
    sharing = demand <= c->q_max ? 1.0 : c->q_max / demand;
    /* the power limiter (plant_models.supply.power_limited, the same operations) */
    if (demand > 0.0 && (p_ls + c->margin * sharing * sharing) * sharing * demand > c->power) {
        for (i = 0; i < 60; i++) {
            const double excess = (p_ls + c->margin * sharing * sharing) * sharing * demand
                                  - c->power;
            const double step = excess / ((p_ls + 3.0 * c->margin * sharing * sharing) * demand);
            sharing -= step;
            if (!(step > 1e-15 * sharing)) break;
        }
    }
    out[0] = p_ls + c->margin * sharing * sharing;
    out[1] = p_ls;
    out[2] = sharing;
}

typedef int (*StepFunction)(const void *call, double t, double h);
typedef int (*StateFunction)(const void *rollback);

typedef struct {
    volatile long which; /* the FMU in a step (0 boom, 1 stick, 2 bucket, 3 pile), -1: none */
    volatile double t;   /* that step's start time, s */
} Board;

typedef struct {
    StepFunction step[4]; /* boom, stick, bucket, pile: fmi2_step, fmi3_step or a callback */
    const void *call[4];  /* their bound calls (fmus.fast_step.StepCall) */
    StateFunction save[3], restore[3]; /* the cylinders' state rollback (implicit only) */
    const void *rollback[3];           /* their bound states (fmus.fast_step.Rollback) */
    double h;             /* communication step, s */
    long steps;           /* the plant's step count: a cylinder steps from steps * h */
    double pile_time;     /* the Pile's clock, s (it steps once more per dump) */
    Board *board;
    long iterations;      /* cylinder steps of the arm coupling since the counter was reset */
    long unconverged;     /* steps that ended at max_iterations above the tolerance */
} Loop;

/* Error codes of coupling_run: (1 + FMU index) << 16 | the FMU call's code. */
static long step_fmu(Loop *loop, int i, double t) {
    loop->board->t = t;
    loop->board->which = i;
    const int code = loop->step[i](loop->call[i], t, loop->h);
    loop->board->which = -1;
    return code ? ((long)(i + 1) << 16) | (code & 0xffff) : 0;
}

static long state_call(Loop *loop, StateFunction *functions, int i, double t) {
    loop->board->t = t;
    loop->board->which = i;
    const int code = functions[i](loop->rollback[i]);
    loop->board->which = -1;
    return code ? ((long)(i + 1) << 16) | (code & 0xffff) : 0;
}

/* x = A^-1 b for a 3 x 3 A (row-major) by Cramer's rule: I + K is diagonally dominant enough
 * (|K_ij| <= coupling ratio < 1) that this is well conditioned. */
static void solve3(const double *A, const double *b, double *x) {
    double c0 = A[4] * A[8] - A[5] * A[7], c1 = A[5] * A[6] - A[3] * A[8];
    double c2 = A[3] * A[7] - A[4] * A[6];
    double det = A[0] * c0 + A[1] * c1 + A[2] * c2;
    x[0] = (b[0] * c0 + A[1] * (b[2] * A[5] - b[1] * A[8]) + A[2] * (b[1] * A[7] - b[2] * A[4]))
           / det;
    x[1] = (A[0] * (b[1] * A[8] - b[2] * A[5]) + b[0] * c1 + A[2] * (b[2] * A[3] - b[1] * A[6]))
           / det;
    x[2] = (A[0] * (b[2] * A[4] - b[1] * A[7]) + A[1] * (b[1] * A[6] - b[2] * A[3]) + b[0] * c2)
           / det;
}

/* One communication step k of the stroke reference (module docstring); 0, 1 when a stroke is
 * not finite (nothing done), 2 when the Pile's bucket mass or soil force is not finite after
 * its step (the cylinders not stepped: a NaN would reach them as their load), else an FMU's
 * error code (step_fmu). */
static long one_step(Coupling *c, Loop *loop) {
    const double h = loop->h, t = (double)loop->steps * h;
    const double *x_ref = c->x_ref + 3 * c->k, *v_ref = c->v_ref + 3 * c->k;
    const double *a_ref = c->a_ref + 3 * c->k;
    double *row = c->rows + c->n_columns * c->k, *joints = c->joints + 3 * c->k;
    const double *pose = c->pose, *pile;
    double x[3], v[3], p_A[3], p_B[3], f[3], base[3], r[3], w[3], d[3], u[3], l[3], m[9];
    double cross[9], force[3], pumped[3] = {0.0, 0.0, 0.0}, mass, force_y, force_z, residual[3];
    double last_force[3], last_v[3], error, jacobian[9], change[3], e_supply[3], e_throttling[3];
    long code;
    int i, j, column, iteration;
    if (!(isfinite(c->cylinder_out[0][0]) && isfinite(c->cylinder_out[1][0])
          && isfinite(c->cylinder_out[2][0]))) {
        return 1;
    }
    kinematics(c, c->cylinder_out[0][0], c->cylinder_out[1][0], c->cylinder_out[2][0]);
    c->pile_in[0] = pose[3];
    c->pile_in[1] = pose[4];
    c->pile_in[2] = -pose[5]; /* the Pile's bucket_angle: the tip-to-pin line */
    code = step_fmu(loop, 3, loop->pile_time);
    if (code) return code;
    loop->pile_time += h;
    pile = c->pile_out;
    mass = pile[0], force_y = pile[1], force_z = pile[2];
    if (!(isfinite(mass) && isfinite(force_y) && isfinite(force_z))) return 2;
    for (i = 0; i < 3; i++) {
        const double *out = c->cylinder_out[i];
        x[i] = out[0], v[i] = out[1], p_A[i] = out[2], p_B[i] = out[3], f[i] = out[4];
        e_supply[i] = out[5], e_throttling[i] = out[6];
        r[i] = pose[6 + i];
        w[i] = v[i] / r[i];
        d[i] = pose[21 + i];
    }
    inertia(c, w[0], w[1], w[2], mass, m);
    /* m: M00, M11, M22, M01, M02, M12, h0, h1, h2 -> the full M (row-major) */
    double M[9] = {m[0], m[3], m[4], m[3], m[1], m[5], m[4], m[5], m[2]};
    for (i = 0; i < 3; i++) {
        /* F_ext_i = [M qdd + h + G - J^T f]_i / r_i with qdd_j = (xdd_j - d_j w_j^2) / r_j:
         * gravity, soil, velocity products and the d-terms here; M_ii xdd_i / r_i^2 is the
         * FMU's mass_load, sum_{j != i} M_ij xdd_j / (r_i r_j) the cross force below. */
        base[i] = (pose[9 + i] + mass * pose[12 + i]
                   - (force_y * pose[16 + 2 * i] - force_z * pose[15 + 2 * i]) + m[6 + i]) / r[i];
        for (j = 0; j < 3; j++) {
            base[i] -= M[3 * i + j] * d[j] * w[j] * w[j] / (r[i] * r[j]);
            cross[3 * i + j] = i == j ? 0.0 : M[3 * i + j] / (r[i] * r[j]);
        }
        l[i] = M[4 * i] / (r[i] * r[i]);
    }
    if (loop->steps % c->servo_every == 0) {
        for (i = 0; i < 3; i++) {
            c->servo[i].held = command(&c->servo[i], x_ref[i], v_ref[i], a_ref[i], x[i], f[i],
                                       l[i]);
        }
    }
    for (i = 0; i < 3; i++) {
        u[i] = c->servo[i].held;
        joints[i] = pose[i];
    }
    if (c->supplied) {
        supply(c, u, p_A, p_B, pumped);
        for (i = 0; i < 3; i++) {
            c->cylinder_in[i][3] = pumped[0];
            c->cylinder_in[i][4] = pumped[1];
        }
    }
    if (c->implicit) {
        for (i = 0; i < 3; i++) {
            /* the last two steps' forces extrapolated: a smooth motion's forces change
             * linearly over a step, so most steps then agree at the first try */
            force[i] = 2.0 * c->force[i] - c->previous_force[i];
            if (!(c->mobility[i] >= 0.0)) c->mobility[i] = h / l[i]; /* none yet: rigid */
            code = state_call(loop, loop->save, i, t);
            if (code) return code;
        }
    } else { /* the planned stroke accelerations */
        for (i = 0; i < 3; i++) {
            force[i] = 0.0;
            for (j = 0; j < 3; j++) force[i] += cross[3 * i + j] * a_ref[j];
        }
    }
    for (iteration = 1;; iteration++) {
        for (i = 0; i < 3; i++) {
            c->cylinder_in[i][0] = u[i];
            c->cylinder_in[i][1] = base[i] + force[i];
            c->cylinder_in[i][2] = l[i];
        }
        for (i = 0; i < 3; i++) {
            code = step_fmu(loop, i, t);
            if (code) return code;
        }
        loop->iterations += 1;
        if (!c->implicit) break;
        error = 0.0;
        for (i = 0; i < 3; i++) {
            residual[i] = -force[i];
            for (j = 0; j < 3; j++) {
                residual[i] += cross[3 * i + j] * (c->cylinder_out[j][1] - v[j]) / h;
            }
            /* as joint acceleration: torque r_i residual_i over the joint's own inertia */
            const double joint = fabs(residual[i] * r[i]) / M[4 * i];
            error = joint > error ? joint : error;
        }
        if (error <= c->tolerance || iteration >= c->max_iterations) {
            if (error > c->tolerance) loop->unconverged += 1;
            break;
        }
        for (i = 0; i < 3; i++) {
            if (iteration > 1) { /* secant of this cylinder's own two iterates */
                const double moved = force[i] - last_force[i];
                const double slope = -(c->cylinder_out[i][1] - last_v[i]) / moved;
                /* 0: a motion the load does not move (an ideal actuator) */
                if (moved != 0.0 && isfinite(slope)) {
                    c->mobility[i] = slope < 0.0 ? 0.0 : (slope > 2.0 * h / l[i] ? 2.0 * h / l[i]
                                                                                 : slope);
                }
            }
            last_force[i] = force[i];
            last_v[i] = c->cylinder_out[i][1];
        }
        for (i = 0; i < 3; i++) {
            for (j = 0; j < 3; j++) {
                jacobian[3 * i + j] = (i == j) + cross[3 * i + j] * c->mobility[j] / h;
            }
        }
        solve3(jacobian, residual, change);
        for (i = 0; i < 3; i++) {
            force[i] += change[i];
            code = state_call(loop, loop->restore, i, t);
            if (code) return code;
        }
    }
    for (i = 0; i < 3; i++) {
        c->previous_force[i] = c->force[i]; /* read by the implicit predictor only */
        c->force[i] = force[i];
    }
    column = 0;
    for (i = 0; i < 3; i++) {
        row[column++] = x[i], row[column++] = v[i], row[column++] = p_A[i];
        row[column++] = p_B[i], row[column++] = f[i];
        /* the energies at t_k, like the other outputs (NaN where the FMU books none) */
        row[column++] = e_supply[i], row[column++] = e_throttling[i], row[column++] = u[i];
        row[column++] = base[i] + force[i], row[column++] = l[i];
    }
    for (i = 0; i < 7; i++) row[column++] = pile[i];
    row[column++] = pose[3], row[column++] = pose[4], row[column++] = pose[5];
    row[column++] = (double)iteration;
    if (c->supplied) {
        row[column++] = pumped[0], row[column++] = pumped[1], row[column++] = pumped[2];
    }
    c->k += 1;
    loop->steps += 1;
    return 0;
}

/* The steps k..n-1 of the stroke reference: 0 when all ran; 1 when a stroke is not finite
 * (nothing of that step done); 2 when the Pile's outputs are not finite (one_step);
 * (1 + FMU index) << 16 | its call's code when an FMU's step or
 * state call failed (its t stays on the board). steps and pile_time advance as each step
 * completes. */
EXPORT long coupling_run(Coupling *c, Loop *loop) {
    while (c->k < c->n) {
        const long code = one_step(c, loop);
        if (code) return code;
    }
    return 0;
}

/* The layout check of the binding: sizeof(Coupling) and the offsets of its parts as this
 * compiler lays them out. */
EXPORT long coupling_size(void) { return (long)sizeof(Coupling); }

EXPORT void coupling_offsets(long *out) {
    out[0] = (long)offsetof(Coupling, n), out[1] = (long)offsetof(Coupling, table);
    out[2] = (long)offsetof(Coupling, lengths), out[3] = (long)offsetof(Coupling, servo);
    out[4] = (long)offsetof(Coupling, supplied), out[5] = (long)offsetof(Coupling, pose);
    out[6] = (long)offsetof(Servo, compensated), out[7] = (long)offsetof(Servo, has_last);
    out[8] = (long)offsetof(Table, inv_dx);
    out[9] = (long)sizeof(Loop), out[10] = (long)offsetof(Loop, pile_time);
    out[11] = (long)offsetof(Loop, board), out[12] = (long)offsetof(Coupling, force);
    out[13] = (long)offsetof(Servo, held), out[14] = (long)offsetof(Loop, unconverged);
}
