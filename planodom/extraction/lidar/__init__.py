"""The lidar (3D) path (many rings, or none): :func:`.path.lidar_planes`."""
