"""robo-gym wire-compatible protocol: the .proto files and their committed generated code.

Regenerate with ``python -m robogym_ray.protocol.regen`` (a test checks the committed files match).
"""
