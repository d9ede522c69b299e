"""The `arduinobot` command: one entry point, one subcommand per job.

- ``main``: the entry point (``arduinobot``, ``python -m arduinobot.cli``), its parser
  and the guard that turns coded errors into exit codes.
- ``commands/``: one module per group of subcommands.
- ``argtypes``: the parsers of joint lists, obstacle specs, goals on the command line.
- ``common``: loading the model from the options, printing summaries, running guarded.
- ``model_log``: the model's warnings held to one line in the commands that only use it.
- ``remote_model``: the service's model fetched and cached for commands that draw or
  simulate it.
- ``see_task``: a task file's ``see`` section on the twin (render, detect, plan).
- ``simulate``: ``plan --simulate`` (the MuJoCo twin as a check).
- ``ros2_execute``, ``ros2_options``: ``execute --ros2`` and the ROS 2 options.
"""
