#!/usr/bin/env python3
"""mlip-listen - watch the setpoint frames mlip-rt puts on a CAN bus.

    mlip-listen.py (--can IFACE | --from-log FILE) [--config FILE] [--profile P]
                   [--csv OUT] [--log OUT] [--json OUT] [--tpdo-csv OUT] [--duration S]
                   [--receive auto|python-can|fast|recvmsg]
    mlip-listen.py --check-layout [--config FILE] [--profile P]

Rebuilds every axis position of every period from the frames of the output
profile (include/mlip/canenc.h, tools/mlip.dbc) and reports what a drive would
have seen: cycles, lost cycles, incomplete cycles, strays, and the period as
seen on the bus.

  cia402  a cycle is a SYNC followed by one RPDO per node; the cycle number is
          the SYNC count from 0 (there is no counter on the wire). Reported: a
          SYNC that arrives before every RPDO of the previous one did
          (incomplete, missing RPDOs), an RPDO twice after one SYNC (duplicate,
          the cycle is dropped), RPDOs with no SYNC before them (stray; a whole
          set of them: a missing SYNC).
  packed  POS frames then a COMMIT carrying the cycle counter: a COMMIT with a
          POS frame missing is incomplete, a POS id twice before a COMMIT
          means the COMMIT was lost, the counter stepping by more than 1 means
          whole cycles lost (gaps), by 0 a duplicate.
  fd      one frame per cycle carrying the counter: gaps and duplicates.

Outputs:
  stdout      one summary line
  --csv OUT   one row per decoded (complete) cycle: cycle,t,x,y,...,cx,cy,...
              t = receive timestamp (s, CLOCK_REALTIME, kernel) of the cycle's
              first frame; positions in mm/deg = counts / COUNTS_PER_UNIT;
              cx,... the raw drive counts
  --log OUT   every frame: candump -l text (.log: (1700000000.123456) vcan0 201#39300000),
              or any format can.Logger writes (.asc, .blf, ...)
  --json OUT  the report: counters, period statistics (min/p50/p99/p99.9/max,
              1-us histogram), first and last positions, socket drops

Live (--can), two receive paths (--receive, default auto):
  python-can  can.Bus on SocketCAN (mlipcan.bus, shared with the drive
              simulator), a can.Notifier feeding the decoder, --log through
              can.Logger (the format by extension: .log candump -L, .asc, .blf).
              Used wherever the kernel has vcan/CAN (a real controller, any
              distribution kernel): python-can keeps up with thousands of
              frames a second there. Kernel drops are not reported
              ("socket_drops": null).
  fast        a raw CAN socket (stdlib, set up as python-can's socketcan
              interface does) read with recvmmsg(2) through ctypes, up to 512
              frames a call, whole regular cycles decoded by slicing; kernel
              timestamps (SO_TIMESTAMPNS) and the drop counter (SO_RXQ_OVFL).
              Used in the software-emulated test VM (MLIP_IN_VM=1: auto picks
              it): there importing python-can alone costs tens of seconds and
              Bus.recv 740-2600 us a frame (cannot keep up with 4000 frames/s),
              the batches about 100 us. --receive recvmsg: one recvmsg a frame.
Both enlarge the receive buffer (SO_RCVBUFFORCE as root, --rcvbuf, default
16 MiB). With a CiA 402 deployment ([DRIVES] ENABLE = 1: 6-byte RPDOs with
the controlword) the drives' TPDOs (statusword, position actual value),
EMCYs, heartbeats and NMT commands are recorded too: the report's "drives"
and "nmt", --tpdo-csv OUT one row per TPDO (t,node,axis,statusword,state,
actual,pos).
SIGTERM/SIGINT: the frames already queued are read, every output is written,
exit 0.

The layout (byte offsets, sizes, signedness of every field) is read from the
DBC with cantools at start-up and checked against the config (axis count,
nodes, ids): a disagreement is an error. cantools is slow to import in the VM,
so what it read is cached in --dbc-cache (default build/) under the DBC's
SHA-256; --check-layout fills the cache and prints the layout. The hot path
then decodes with struct and slicing. Exit status: 0 done, 1 runtime error
(interface, log file), 2 usage or a layout mismatch.
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from mlipcan.listen import main  # noqa: E402  (tools/mlipcan/: bus, setup, layout, decoders, sources, report)

if __name__ == "__main__":
    sys.exit(main())
