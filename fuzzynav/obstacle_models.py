"""fuzzynav's own obstacle models: importing this module registers them (:mod:`fuzzynav.obstacle_model`).

One module per model, named after it; adding one is a new module with ``@register_obstacle_model("name")`` and a
line here.
"""

from fuzzynav import pedestrian_orca, random_walk, scripted_motion, social_force

BUILTIN = (scripted_motion.ScriptedModel, social_force.SocialForceModel, pedestrian_orca.PedestrianOrcaModel,
           random_walk.RandomWalkModel)
"""The built-in models, in the order the README lists them."""
