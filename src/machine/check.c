/*
 * check.c - the machine check (mlip_machine_check), shared by the INI
 * reader (which places its error on the key that set the value) and the
 * tools' command-line overrides.
 */
#include <math.h>

#include "keys.h"

static void sb_field(struct mlip_tb *b, const struct mlip_machine *m, int axis, int key)
{
	if (axis < 0) {
		mlip_tb_puts(b, "TRAJ ");
		mlip_tb_puts(b, mlip_mc_keytab[K_TRAJ][key].name);
	} else {
		mlip_tb_puts(b, "AXIS_");
		mlip_tb_putc(b, m->axis[axis].letter);
		mlip_tb_putc(b, ' ');
		mlip_tb_puts(b, mlip_mc_keytab[K_AXIS][key].name);
	}
}

/* A limit: finite and > 0. */
static int bad_pos(struct mlip_tb *b, const struct mlip_machine *m, int axis, int key, double v)
{
	if (isfinite(v) && v > 0) {
		return 0;
	}
	sb_field(b, m, axis, key);
	mlip_tb_puts(b, isfinite(v) ? " must be > 0, got " : " must be finite, got ");
	mlip_tb_double(b, v);
	return 1;
}

static int bad_finite(struct mlip_tb *b, const struct mlip_machine *m, int axis, int key, double v)
{
	if (isfinite(v)) {
		return 0;
	}
	sb_field(b, m, axis, key);
	mlip_tb_puts(b, " must be finite, got ");
	mlip_tb_double(b, v);
	return 1;
}

/* A limit at most max ("must be at most 1e6, got 2e6"). */
static int bad_max(struct mlip_tb *b, const struct mlip_machine *m, int axis, int key, double v,
                   double max)
{
	if (v <= max) {
		return 0;
	}
	sb_field(b, m, axis, key);
	mlip_tb_puts(b, " must be at most ");
	mlip_tb_double(b, max);
	mlip_tb_puts(b, ", got ");
	mlip_tb_double(b, v);
	return 1;
}

/* |x| at most MLIP_CONFIG_LIMIT_MAX. */
static int bad_abs(struct mlip_tb *b, const struct mlip_machine *m, int axis, int key, double v)
{
	if (fabs(v) <= MLIP_CONFIG_LIMIT_MAX) {
		return 0;
	}
	sb_field(b, m, axis, key);
	mlip_tb_puts(b, " must be within -1e9..1e9, got ");
	mlip_tb_double(b, v);
	return 1;
}

/*
 * The period against the contour tolerance. Each setpoint lies on the planned
 * curve, which stays within eps of the polyline ((17)(18): a corner of
 * acceleration a lasting t_m deviates by |a| t_m^2 / 8). Between two
 * setpoints, though, a drive in cyclic synchronous position mode moves in a
 * straight line, and a motion with |acceleration| <= a departs from the chord
 * of one period by up to a T^2 / 8: the same bound (17) gives for a corner
 * passed in one period, the bisector method's case (10). At the machine's
 * full acceleration, |A| = sqrt(sum A_k^2) (the polygon's farthest vertex,
 * Theorem 2), that must not exceed eps:
 *     |A| T^2 / 8 <= eps   <=>   T <= sqrt(8 eps / |A|)
 * (1 ms, 0.01 mm: |A| up to 80000 mm/s^2). A longer period is refused: the
 * machine could cut corners by more than the whole tolerance between
 * setpoints (at T = 0.1 s and 1000 mm/s^2 per axis, by 2 mm).
 */
static mlip_status check_period(const struct mlip_machine *m, struct mlip_tb *b, struct issue *is)
{
	double a2 = 0.0, amax = 0.0, dev, tmax;
	int i;

	for (i = 0; i < m->n_axes; i++) {
		a2 += m->axis[i].max_accel * m->axis[i].max_accel;
		if (m->axis[i].max_accel > amax) {
			amax = m->axis[i].max_accel;
			is->axis2 = i;
		}
	}
	dev = sqrt(a2) * m->period_s * m->period_s / 8.0;
	if (dev <= m->tolerance_mm) {
		is->axis2 = -1;
		return MLIP_OK;
	}
	tmax = sqrt(8.0 * m->tolerance_mm / sqrt(a2));
	is->key = TK_PERIOD;
	mlip_tb_puts(b, "TRAJ PERIOD ");
	mlip_tb_double(b, m->period_s);
	mlip_tb_puts(b, " s is too long for CONTOUR_TOLERANCE ");
	mlip_tb_double(b, m->tolerance_mm);
	mlip_tb_puts(b, " mm: between two setpoints the path may leave the curve by |A| T^2/8 = ");
	mlip_tb_double(b, floor(dev * 1e6 + 0.5) / 1e6);
	mlip_tb_puts(b, " mm (|A| = ");
	mlip_tb_double(b, floor(sqrt(a2) + 0.5));
	mlip_tb_puts(b, " mm/s^2, eq. 17); PERIOD must be at most ");
	mlip_tb_double(b, floor(tmax * 1e6) / 1e6);
	mlip_tb_puts(b, " s");
	return MLIP_E_RANGE;
}

mlip_status mlip_mc_check_machine(const struct mlip_machine *m, struct mlip_config_error *err,
                                  struct issue *is)
{
	struct mlip_tb b;
	int i, j;

	err_at(err, &b, 0, 0);
	is->axis = -1;
	is->key = -1;
	is->axis2 = -1;
	if (m->n_axes < 2 || m->n_axes > MLIP_MAX_AXES) {
		mlip_tb_puts(&b, "TRAJ COORDINATES must have 2 to 6 axes, got ");
		if (m->n_axes < 0) {
			mlip_tb_putc(&b, '-');
		}
		mlip_tb_uint(&b, (uint64_t)(m->n_axes < 0 ? -(int64_t)m->n_axes : m->n_axes));
		is->key = TK_COORDS;
		return MLIP_E_INVALID;
	}
	if (m->smooth > 1) {
		/* not from an INI: a published segment's flag (mlip-rt --strategy) */
		mlip_tb_puts(&b, "the smooth flag must be 0 or 1, got ");
		mlip_tb_uint(&b, m->smooth);
		return MLIP_E_INVALID;
	}
	is->key = TK_VLIN;
	if (bad_pos(&b, m, -1, TK_VLIN, m->max_feed_mm_s) ||
	    bad_max(&b, m, -1, TK_VLIN, m->max_feed_mm_s, MLIP_CONFIG_VEL_MAX)) {
		return MLIP_E_RANGE;
	}
	is->key = TK_VANG;
	if (bad_pos(&b, m, -1, TK_VANG, m->max_rot_feed_deg_s) ||
	    bad_max(&b, m, -1, TK_VANG, m->max_rot_feed_deg_s, MLIP_CONFIG_VEL_MAX)) {
		return MLIP_E_RANGE;
	}
	is->key = TK_TOL;
	if (bad_pos(&b, m, -1, TK_TOL, m->tolerance_mm)) {
		return MLIP_E_RANGE;
	}
	if (m->tolerance_mm < MLIP_CONFIG_TOL_MIN) {
		mlip_tb_puts(&b, "TRAJ CONTOUR_TOLERANCE must be at least 1e-6 mm, got ");
		mlip_tb_double(&b, m->tolerance_mm);
		return MLIP_E_RANGE;
	}
	is->key = TK_PERIOD;
	if (!(m->period_s >= MLIP_CONFIG_PERIOD_MIN_S && m->period_s <= MLIP_CONFIG_PERIOD_MAX_S)) {
		mlip_tb_puts(&b, "TRAJ PERIOD must be within 0.0001..0.1 s, got ");
		mlip_tb_double(&b, m->period_s);
		return MLIP_E_RANGE;
	}
	for (i = 0; i < m->n_axes; i++) {
		const struct mlip_axis *a = &m->axis[i];
		is->axis = i;
		is->key = TK_COORDS; /* letter problems: no AXIS_ key to point at */
		if (letter_index(a->letter) < 0) {
			mlip_tb_puts(&b, "TRAJ COORDINATES: axis ");
			mlip_tb_uint(&b, (uint64_t)i);
			mlip_tb_puts(&b, " has letter ");
			mlip_tb_byte(&b, (unsigned char)a->letter);
			mlip_tb_puts(&b, ", not one of X Y Z A B C");
			is->axis = -1;
			return MLIP_E_INVALID;
		}
		for (j = 0; j < i; j++) {
			if (m->axis[j].letter == a->letter) {
				mlip_tb_puts(&b, "TRAJ COORDINATES: duplicate axis letter ");
				mlip_tb_putc(&b, a->letter);
				is->axis = -1;
				return MLIP_E_INVALID;
			}
		}
		is->key = AK_TYPE;
		if (a->kind != MLIP_AXIS_LINEAR && a->kind != MLIP_AXIS_ROTARY) {
			sb_field(&b, m, i, AK_TYPE);
			mlip_tb_puts(&b, " must be LINEAR or ANGULAR");
			return MLIP_E_INVALID;
		}
		is->key = AK_VEL;
		if (bad_pos(&b, m, i, AK_VEL, a->max_vel) ||
		    bad_max(&b, m, i, AK_VEL, a->max_vel, MLIP_CONFIG_VEL_MAX)) {
			return MLIP_E_RANGE;
		}
		is->key = AK_ACC;
		if (bad_pos(&b, m, i, AK_ACC, a->max_accel) ||
		    bad_max(&b, m, i, AK_ACC, a->max_accel, MLIP_CONFIG_ACCEL_MAX)) {
			return MLIP_E_RANGE;
		}
		is->key = AK_JERK; /* 0: no jerk limit (mlip/motion/jerk.h) */
		if (a->max_jerk != 0.0 &&
		    (bad_pos(&b, m, i, AK_JERK, a->max_jerk) ||
		     bad_max(&b, m, i, AK_JERK, a->max_jerk, MLIP_CONFIG_JERK_MAX))) {
			return MLIP_E_RANGE;
		}
		is->key = AK_MIN;
		if (bad_finite(&b, m, i, AK_MIN, a->min_limit) ||
		    bad_abs(&b, m, i, AK_MIN, a->min_limit)) {
			return MLIP_E_RANGE;
		}
		is->key = AK_MAX;
		if (bad_finite(&b, m, i, AK_MAX, a->max_limit) ||
		    bad_abs(&b, m, i, AK_MAX, a->max_limit)) {
			return MLIP_E_RANGE;
		}
		is->key = AK_MIN; /* the pair: the parser points at the later key */
		if (!(a->min_limit < a->max_limit)) {
			sb_field(&b, m, i, AK_MIN);
			mlip_tb_puts(&b, " must be < MAX_LIMIT, got ");
			mlip_tb_double(&b, a->min_limit);
			mlip_tb_puts(&b, " >= ");
			mlip_tb_double(&b, a->max_limit);
			return MLIP_E_RANGE;
		}
		is->key = AK_HOME;
		if (bad_finite(&b, m, i, AK_HOME, a->home)) {
			return MLIP_E_RANGE;
		}
		if (a->home < a->min_limit || a->home > a->max_limit) {
			sb_field(&b, m, i, AK_HOME);
			mlip_tb_putc(&b, ' ');
			mlip_tb_double(&b, a->home);
			mlip_tb_puts(&b, " is outside MIN_LIMIT..MAX_LIMIT ");
			mlip_tb_double(&b, a->min_limit);
			mlip_tb_puts(&b, "..");
			mlip_tb_double(&b, a->max_limit);
			return MLIP_E_RANGE;
		}
		is->key = AK_NODE;
		if (a->can_node < 1 || a->can_node > MLIP_CAN_NODE_MAX) {
			sb_field(&b, m, i, AK_NODE);
			mlip_tb_puts(&b, " must be within 1..127, got ");
			if (a->can_node < 0) {
				mlip_tb_putc(&b, '-');
			}
			mlip_tb_uint(
			    &b, (uint64_t)(a->can_node < 0 ? -(int64_t)a->can_node : a->can_node));
			return MLIP_E_RANGE;
		}
		for (j = 0; j < i; j++) {
			if (m->axis[j].can_node == a->can_node) {
				sb_field(&b, m, i, AK_NODE);
				mlip_tb_putc(&b, ' ');
				mlip_tb_uint(&b, (uint64_t)a->can_node);
				mlip_tb_puts(&b, " is also the CAN_NODE of AXIS_");
				mlip_tb_putc(&b, m->axis[j].letter);
				is->axis2 = j;
				return MLIP_E_RANGE;
			}
		}
		is->key = AK_CPU;
		if (bad_pos(&b, m, i, AK_CPU, a->counts_per_unit) ||
		    bad_max(&b, m, i, AK_CPU, a->counts_per_unit, MLIP_CONFIG_COUNTS_MAX)) {
			return MLIP_E_RANGE;
		}
	}
	is->axis = -1;
	is->key = -1;
	return check_period(m, &b, is);
}

mlip_status mlip_machine_check(const struct mlip_machine *m, struct mlip_config_error *err)
{
	struct mlip_config_error dummy;
	struct issue is;

	return mlip_mc_check_machine(m, err != NULL ? err : &dummy, &is);
}
