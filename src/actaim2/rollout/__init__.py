"""Rollouts in simulation: the layer on top of both :mod:`actaim2.sim` and :mod:`actaim2.control`.

``sim`` (the SAPIEN world) and ``control`` (IK, trajectories, keypose execution) do not import
each other; what needs both lives here:

  sim_executor   SimEnvExecutor: executes control's trajectories and gripper commands in a SimEnv
  expert         the scripted expert with privileged state (proves objects are manipulable)
  expert_eval    its success table per category (`actaim2 expert`)
"""
