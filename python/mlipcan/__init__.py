"""mlip's Python side: the CAN listener, the simulated CiA 402 drives, the
end-to-end harness of the demo and the CAN tests. Installed into the
project's .venv by tools/deps.sh (pip install -e .); console scripts
mlip-listen, mlip-drive-sim, mlip-demo.

  settings     where things are (repository, build, shared toolpaths) and how
               the end-to-end runs behave: one value, passed as an argument
  config       the machine INI as mlip-config --json reads it (Setup, limits)
  bus          a python-can bus on SocketCAN
  layout       frame layouts read from tools/mlip.dbc with cantools (cached)
  decoders     the setpoint stream of each output profile -> cycles, anomalies
  sources      where frames come from: python-can, recvmmsg batches, logs
  report       the listener's outputs (CSV, candump log, period statistics)
  listen       the listener's command line (mlip-listen)
  cia402       the CiA 402 / CiA 301 numbers (statusword, controlword, aborts)
  drive        simulated CiA 402 servo drives on the canopen package
  drivesim     their command line (mlip-drive-sim)
  procs        process control: the C tools, mlip-rt + listener (Rig), drives
  compare      setpoints in counts: mlip-sim against the bus and the drives
  demo         the demo's bus stage; demo_drives: its drives stage
  plot         the demo's speed plot (matplotlib)
  democli      the demo's command line (mlip-demo)

Modules import python-can, cantools, canopen or matplotlib only where they
need them: each costs tens of seconds in the software-emulated test VM.
"""
