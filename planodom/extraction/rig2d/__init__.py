"""The 2D-scanner-rig path (few rings): :func:`.path.rig2d_planes`."""
