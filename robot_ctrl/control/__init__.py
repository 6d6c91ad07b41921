"""Control: what runs the pipeline's stages on a robot, tick by tick.

- ``controllers``: a controller turns a measured ``JointState`` into a ``JointCommand`` (walking,
  balance, joint playback) and the parts it is built from (DCM stabilizer, torque feedforward).
- ``commanders``: what steers a controller through its commands (a path, the walk-and-reach
  synthesis, the crowd's coupling, the drawer task's hands).
- ``loop``: the control loop that runs controllers on hardware, its pacer and the start sequence.
- ``estimation``: the CoM, DCM and ZMP, the floating base and its attitude, from what is measured.
"""
