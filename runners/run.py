"""Run episodes of one configuration and print their outcomes.

    python -m runners.run                                  # the default: head_on, Table 1, strategy auto
    python -m runners.run scenario=head_on planner.strategy=none episodes=3

Configuration is composed by Hydra from ``conf/config.yaml``; any key can be overridden.
"""

from __future__ import annotations

import sys
from typing import Any

import hydra
from omegaconf import DictConfig, OmegaConf

from fuzzynav.config import episode_config_from_dict
from fuzzynav.episode import Episode
from fuzzynav.fuzzy_fast import FastEvaluator
from fuzzynav.fuzzy_spec import ControllerSpec, ControllerSpecError
from fuzzynav.scenario import ScenarioError, scenario_from_dict


def run(cfg: dict[str, Any]) -> list[dict[str, Any]]:
    """Run ``cfg["episodes"]`` episodes with consecutive seeds; return one summary per episode."""
    scenario = scenario_from_dict(cfg["scenario"])
    evaluator = FastEvaluator(ControllerSpec.from_dict(cfg["controller"]))
    episode_cfg = episode_config_from_dict(cfg.get("episode", {}))
    results = []
    for k in range(int(cfg.get("episodes", 1))):
        seed = int(cfg.get("seed", 0)) + k
        ep = Episode(scenario, evaluator, episode_cfg, seed=seed)
        steps = sum(1 for _ in ep.run())
        results.append({"scenario": scenario.name, "strategy": episode_cfg.planner.strategy, "seed": seed,
                        "outcome": ep.outcome, "steps": steps, "time_s": steps * episode_cfg.dt,
                        "contacts": ep.contacts})
    return results


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
def main(cfg: DictConfig) -> None:
    plain = OmegaConf.to_container(cfg, resolve=True)
    try:
        results = run(plain)  # type: ignore[arg-type]
    except (ScenarioError, ControllerSpecError) as err:
        print(f"error: {err}", file=sys.stderr)
        sys.exit(2)
    except ValueError as err:
        print(f"error: config: {err}", file=sys.stderr)
        sys.exit(2)
    for r in results:
        print(f"{r['scenario']} strategy={r['strategy']} seed={r['seed']}: {r['outcome']} after {r['steps']} "
              f"steps ({r['time_s']:.0f} s), contacts={r['contacts']}")


if __name__ == "__main__":
    main()
