"""World motion on the SMPL 24-joint kinematic tree: the skeleton the field's dance generators
train on (AIST++, EDGE, Bailando, FineDance, AIOZ-GDANCE). ``skeleton`` holds the tree as data,
``retarget`` solves joint rotations from world joints, ``kinematics`` goes back (forward
kinematics), ``checks`` measures what the retargeting kept."""
