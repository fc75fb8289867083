"""Human mocap → humanoid upper body (LWL2): pose15, capsules, WAEs, LA-DPP, LWR, transition graph."""
