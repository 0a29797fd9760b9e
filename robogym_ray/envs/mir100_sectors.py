"""MiR100 obstacle avoidance that observes the nearest laser return around each of its 16 beams.

Why: robo-gym's ObstacleAvoidance observation keeps 16 of the 1012 laser ranges, about 67
beams (~34 degrees of a scanner's sweep, at 0.5 degrees per beam) apart. A cube edge or a
narrow gap between two cubes can fall between two kept beams, so the policy may read a gap as
open that the 0.40 m footprint rule closes. The policies trained on it fail mostly such starts
(``docs/results-log.md``, "Where navigation fails"). This variant keeps the task (scene, resets,
reward, collision rules, episode ends) and the meaning of each observation index: value ``i``
is the *nearest* return among the beams around robo-gym's beam ``i``, instead of that one
beam's range. A real MiR100 gives the same 1012 ranges, so the Rob variant needs nothing more.

It is not robo-gym's observation: a policy trained on one does not run on the other.
"""

from __future__ import annotations

import numpy as np

from robogym_ray.envs.mir100_tasks import LASER, LASER_OFFSETS, ObstacleAvoidanceMir100
from robogym_ray.protocol import robot_server_pb2 as pb

SECTOR_STARTS = np.concatenate([[0], (LASER_OFFSETS[:-1] + LASER_OFFSETS[1:] + 1) // 2])
"""First raw-range index of each of the 16 sectors. Sector ``i`` runs from halfway between
robo-gym's beams ``i - 1`` and ``i`` up to halfway to beam ``i + 1`` (the first and last sectors
end at the scan's ends), so each sector contains robo-gym's beam ``i`` and every raw range
belongs to exactly one sector."""


class ObstacleAvoidanceSectorsMir100(ObstacleAvoidanceMir100):
    """``ObstacleAvoidanceMir100`` with the nearest range per laser sector (see module doc).

    ## Observation space
    ``Box((20,), float32)``: indices 0-3 as in ``ObstacleAvoidanceMir100``; 4-19 = for each
    of the 16 sectors of the raw ranges ``state[8:1020]`` (``SECTOR_STARTS``), the smallest
    range in it (m, [0, 29]). A NaN anywhere in the raw ranges makes its sector NaN, which the
    space check refuses with ``InvalidStateError``.

    Everything else (actions, reward, episode end, reset, arguments) is
    ``ObstacleAvoidanceMir100``'s.
    """

    def _to_obs(self, msg: pb.State) -> np.ndarray:
        ranges = np.asarray(msg.state[LASER], dtype=np.float32)
        return np.concatenate([self._nav_obs(msg), np.minimum.reduceat(ranges, SECTOR_STARTS)])
