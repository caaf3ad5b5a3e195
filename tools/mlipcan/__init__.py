"""mlip's CAN tooling (Python side), shared by tools/mlip-listen.py,
tools/mlip-drive-sim.py, tools/demo.sh and the CAN tests (tests/can):

  bus       open a SocketCAN bus with python-can (can.Bus), or the fast raw
            socket the listener uses inside the emulated test VM
  setup     the machine INI as the CAN tools need it (axes, nodes, counts, ids)
  layout    frame layouts read from tools/mlip.dbc with cantools (cached)
  decoders  the setpoint stream of each output profile -> cycles and anomalies
  sources   where frames come from: python-can, recvmmsg batches, candump logs
  report    the listener's outputs (CSV, candump log, JSON report)
  listen    the listener's command line (tools/mlip-listen.py)
  cia402    the CiA 402 / CiA 301 numbers (statusword, controlword, abort codes)
  drive     simulated CiA 402 servo drives on the canopen package
  harness   running mlip-rt + listener + mlip-feed end to end (demo, tests)

Modules import python-can, cantools or canopen only where they need them:
each costs tens of seconds in the software-emulated test VM.
"""
