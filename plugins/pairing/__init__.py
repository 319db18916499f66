"""Real/mirror pairing (issue [demo] item 4): each marker with its image in each plane mirror.

A marker and its mirror image lie on a line through the mirror epipole (the image of the virtual
camera centre); pairs are chosen by an optimal assignment under that constraint and an ordering
rule, with track continuity when the previous frame's pairs are given. Ambiguous pairs are
reported, never guessed.
"""

from .epipole import mirror_epipole, projection_matrix, undistort_points
from .errors import InvalidPairingInput, PairingError
from .pair import AmbiguousPair, MirrorPairs, epipolar_distance, ordering_ok, pair_mirror
from .regions import mirror_of_points

__all__ = ["AmbiguousPair", "InvalidPairingInput", "MirrorPairs", "PairingError", "epipolar_distance",
           "mirror_epipole", "mirror_of_points", "ordering_ok", "pair_mirror", "projection_matrix",
           "undistort_points"]
