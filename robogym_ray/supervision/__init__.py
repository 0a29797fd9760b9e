"""Robot-server supervision, without Ray: the supervisor, its restart policy, health probes,
the robot-server host and robo-gym's ServerManager service. ``distributed/`` runs them on Ray."""
