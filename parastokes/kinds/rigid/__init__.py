"""Rigid and prescribed-motion bodies: surfaces whose motion is found by a mobility solve.

A rigid body (:class:`.system.RigidBody`) is a surface point cloud in its body frame
(:mod:`.shapes`: sphere, spheroid, rod, helix, a user's cloud, a bacterium), a pose (centre and
unit quaternion), an optional prescribed surface velocity (:mod:`.slip`: squirmer, a user's
function; a bacterium's rotating flagellum) and an optional external force and torque. Each
evaluation solves for its (U, Ω) (docs/bodies.md, "Rigid bodies").
"""

from .shapes import Bacterium, Helix, PointCloud, Rod, Sphere, Spheroid
from .slip import Squirmer, UserSlip
from .system import RigidBody

__all__ = ["Bacterium", "Helix", "PointCloud", "RigidBody", "Rod", "Sphere", "Spheroid",
           "Squirmer", "UserSlip"]
