"""Motion retargeting: keypoint motions onto quadrupeds (STMR) and human mocap onto humanoid arms (LWL2).

Data flows one way: source file → importer → KeypointMotion → UVM / SMR → TMR → RobotMotion → export;
mocap → 15-d pose → latent → LWR / BFS → upper-body joint targets.
"""
