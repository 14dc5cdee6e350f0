"""Moving obstacles: the obstacle-model seam (:mod:`.base`), one module per model (scripted, social force, ORCA,
random walk) and the crowd that steps them all. A module of this package registers itself; another package's
model is an entry point of group ``fuzzynav.pedestrians``."""
