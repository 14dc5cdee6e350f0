"""Navigation policies: the seam (:mod:`.base`: ``Policy``, ``Observation``, ``Action``, ``register_policy``) and
one module per method (the paper's fuzzy controller and the baselines DWA, APF, VFH, ORCA, direct). A module
of this package registers itself; another package's policy is an entry point of group ``fuzzynav.policies``."""
