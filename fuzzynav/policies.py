"""fuzzynav's own navigation policies: importing this module registers them (:mod:`fuzzynav.policy`).

One module per method, named after it; adding one is a new module with ``@register_policy("name")``, a line
here and ``conf/navigator/<name>.yaml``.
"""

from fuzzynav import apf, direct, dwa, fuzzy_policy, orca, vfh

BUILTIN = (fuzzy_policy.FuzzyPolicy, dwa.DWAPolicy, apf.ApfPolicy, vfh.VfhPolicy, orca.OrcaPolicy,
           direct.DirectPolicy)
"""The built-in policies, in the order the README lists them."""
