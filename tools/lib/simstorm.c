/* simstorm.c - see simstorm.h */
#include "simstorm.h"

/* xorshift64*: a seeded, portable stream for --storm */
static uint64_t rng_next(uint64_t *s)
{
	*s ^= *s >> 12;
	*s ^= *s << 25;
	*s ^= *s >> 27;
	return *s * 2685821657736338717ULL;
}

static double rng_unit(uint64_t *s)
{
	return (double)(rng_next(s) >> 11) * (1.0 / 9007199254740992.0);
}

int mlip_simstorm_tick(struct mlip_simstorm *st, uint64_t period, struct mlip_ring_cmd *cmd)
{
	if (!st->active || period < st->next_at) {
		return 0;
	}
	st->next_at = period + 5 + rng_next(&st->state) % 196;
	st->events++;
	double r = rng_unit(&st->state);
	cmd->arg = 0;
	if (st->held) {
		cmd->op = MLIP_CMD_RESUME;
		st->held = 0;
	} else if (st->zero) {
		cmd->op = MLIP_CMD_OVERRIDE;
		cmd->arg = (int32_t)(10.0 + 190.0 * rng_unit(&st->state));
		st->zero = 0;
	} else if (r < 0.1) {
		cmd->op = MLIP_CMD_HOLD;
		st->held = 1;
	} else if (r < 0.2) {
		cmd->op = MLIP_CMD_OVERRIDE;
		st->zero = 1;
	} else {
		cmd->op = MLIP_CMD_OVERRIDE;
		cmd->arg = (int32_t)(10.0 + 190.0 * rng_unit(&st->state));
	}
	return 1;
}
