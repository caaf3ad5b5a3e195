/*
 * rtparts.c - parts of mlip-rt (tools/mlip-rt.c) that need no state of it:
 * the bus-load budget checked at start-up and a process's name for the log.
 * Not a library: only mlip-rt links these.
 */
#include "rtparts.h"

#include <stdio.h>
#include <string.h>

#include "mlip/can/canenc.h"
#include "rt.h"

#define PROG         "mlip-rt"
#define MAX_BUS_LOAD 0.70

/* The frames a period puts on the bus against the bit rate: refused above
 * MAX_BUS_LOAD (printed either way). */
int mlip_rt_bus_budget(const struct mlip_config *cfg, mlip_can_profile prof)
{
	struct mlip_can_load l;
	if (mlip_can_load_breakdown(prof, cfg->machine.n_axes, cfg->can.bitrate,
	                            cfg->can.data_bitrate, cfg->machine.period_s, &l) != MLIP_OK) {
		fprintf(stderr, PROG ": cannot compute the bus load for this profile\n");
		return -1;
	}
	if (cfg->drives.enable) {
		/* RPDOs of 6 bytes (controlword), a 6-byte TPDO back from each drive,
		 * heartbeats of the drives and the master (1 byte each) */
		/* the touch probe ([PROBE] SOURCE = drive): RPDO and TPDO of 8 bytes,
		 * a second 8-byte TPDO (the latched positions); the drives' digital
		 * inputs: a 4-byte TPDO3 at least every heartbeat (its event timer) */
		int n = cfg->machine.n_axes;
		int tp = cfg->inputs.probe_source == MLIP_PROBE_SRC_DRIVE;
		int n_di = 0;
		for (uint32_t di = mlip_drives_di_axes(cfg); di != 0; di &= di - 1) {
			n_di++;
		}
		uint8_t pdo = tp ? 8 : 6;
		double hb = cfg->machine.period_s / (cfg->drives.heartbeat_ms * 1e-3);
		double bits =
		    n * ((double)mlip_can_frame_bits(0, pdo).nominal -
		         mlip_can_frame_bits(0, 4).nominal + mlip_can_frame_bits(0, pdo).nominal +
		         (tp ? mlip_can_frame_bits(0, 8).nominal : 0.0)) +
		    (n + 1) * hb * mlip_can_frame_bits(0, 1).nominal +
		    n_di * hb * mlip_can_frame_bits(0, 4).nominal;
		/* a CiA 402 spindle: one more drive, a 6-byte RPDO (controlword,
		 * target velocity) and TPDO (statusword, velocity actual) every
		 * SYNC and its heartbeat */
		int sp = cfg->io.spindle == MLIP_IO_CIA402;
		if (sp) {
			bits += 2.0 * mlip_can_frame_bits(0, 6).nominal +
			        hb * mlip_can_frame_bits(0, 1).nominal;
		}
		/* the I/O module (issue 18/19): its heartbeat, its inputs' TPDO
		 * (on a change, counted once a heartbeat as the drives' TPDO3)
		 * and its outputs' RPDO (on a change and every 100 ms) */
		if (cfg->inputs.node != 0) {
			uint8_t in_b = cfg->inputs.in_bytes ? (uint8_t)cfg->inputs.in_bytes : 1;
			bits += hb * (mlip_can_frame_bits(0, 1).nominal +
			              mlip_can_frame_bits(0, in_b).nominal);
			if (cfg->inputs.out_bytes > 0) {
				bits +=
				    cfg->machine.period_s / 0.1 *
				    mlip_can_frame_bits(0, (uint8_t)cfg->inputs.out_bytes).nominal;
			}
		}
		l.busy_s += bits / cfg->can.bitrate;
		l.load = l.busy_s / cfg->machine.period_s;
		l.frames += (tp ? 2 * n : n) + 2 * sp;
	}
	fprintf(stderr,
	        PROG ": bus load %.1f %% (%s, %d frames per %.3f ms period, %.0f us of %u bit/s)\n",
	        l.load * 100.0, mlip_can_profile_name(prof), l.frames, cfg->machine.period_s * 1e3,
	        l.busy_s * 1e6, cfg->can.bitrate);
	if (l.load > MAX_BUS_LOAD) {
		fprintf(stderr,
		        PROG
		        ": refusing: %.1f %% is above the %.0f %% budget; use a faster bit rate, "
		        "the packed or fd profile, or a longer period\n",
		        l.load * 100.0, MAX_BUS_LOAD * 100.0);
		return -1;
	}
	return 0;
}

/* Process pid's name (/proc/PID/comm), or "?" */
void mlip_rt_process_name(int32_t pid, char *out, size_t n)
{
	char path[40];
	FILE *f;
	snprintf(path, sizeof(path), "/proc/%d/comm", (int)pid);
	snprintf(out, n, "?");
	f = fopen(path, "r");
	if (f == NULL) {
		return;
	}
	if (fgets(out, (int)n, f) == NULL) {
		snprintf(out, n, "?");
	}
	out[strcspn(out, "\n")] = '\0';
	fclose(f);
}
