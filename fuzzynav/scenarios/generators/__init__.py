"""fuzzynav's scenario generators, one module each (the seam: :mod:`fuzzynav.scenarios.generator`)."""
