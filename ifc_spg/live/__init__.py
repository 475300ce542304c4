"""Live runs over DDS that are not the nodes: recording and playing bags."""
