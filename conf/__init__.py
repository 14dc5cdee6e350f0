"""fuzzynav's Hydra configuration, installed as the package ``fuzzynav.conf``: ``config.yaml`` and one config
group per seam of the code (``controller``, ``navigator``, ``planner``, ``scenario``, ...), plus sweep presets."""

from pathlib import Path

#: the folder of ``config.yaml`` (a real folder: in the checkout, or in site-packages after ``pip install``)
CONF_DIR = Path(__file__).resolve().parent
