"""The campaign: period after period, adapt D, plan the trajectory, dig, weigh and log.

    from orchestrator.campaign import run_campaign
    result = run_campaign("scenarios/paper-2020.toml", log_path="run.mcap")
"""

from orchestrator.campaign.loop import INTERRUPTED, CampaignResult, PlantRefused, run_campaign

__all__ = ["INTERRUPTED", "CampaignResult", "PlantRefused", "run_campaign"]
