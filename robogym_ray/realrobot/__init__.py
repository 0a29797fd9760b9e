"""A real robot behind a gRPC robot server: the safety filter and the pause/resume wrapper
that the training program drives (never restarted, never a simulation)."""
