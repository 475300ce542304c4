"""MuJoCo bridge: robots, scenes and emulated IFC interfaces (LBR FRI, iCub, ACCREA)."""
