"""The Feetech STS/SCS bus-servo driver (``--driver feetech``): LeRobot's SO-100/SO-101.

- :mod:`~arduinobot.execution.robots.feetech.protocol`: the bus's packets (PING, READ,
  WRITE, SYNC_READ, SYNC_WRITE), checksum, the registers used, the servos' errors;
- :mod:`~arduinobot.execution.robots.feetech.calibration`: LeRobot's calibration file and
  joint angles <-> servo ticks;
- :mod:`~arduinobot.execution.robots.feetech.driver`:
  :class:`~arduinobot.execution.robots.feetech.driver.FeetechArm`, the driver, its
  torque policy and tracking check.

Our own packet code on pyserial rather than Feetech's ``scservo_sdk``
(``feetech-servo-sdk`` 1.0.0): that SDK keeps the byte order in a module global, polls
the port in a busy loop (a core per read) and times out on the wall clock; our protocol
module is ~250 lines with its documentation.
"""
