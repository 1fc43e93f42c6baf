"""The plane builder shared by both extraction paths: robust TLS fits and their covariance
(:mod:`.fit`), CPEF confidence (:mod:`.confidence`), support polygon and label
(:mod:`.support`), and :func:`.builder.build_planes`, which turns fits into oriented planes."""
