/*
 * rtparts.h - the parts of mlip-rt beside it (tools/rtparts.c).
 */
#ifndef MLIP_TOOLS_RTPARTS_H
#define MLIP_TOOLS_RTPARTS_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/can/canenc.h"
#include "mlip/machine/config.h"

int mlip_rt_bus_budget(const struct mlip_config *cfg, mlip_can_profile prof);
void mlip_rt_process_name(int32_t pid, char *out, size_t n);

#endif
