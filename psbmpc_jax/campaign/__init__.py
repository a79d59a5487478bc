"""Campaigns: scenarios x methods x seeds x runs cut into tasks, run by a local or a Ray engine, each task's rows
written atomically (resume after a crash), and one tidy table per campaign (docs/campaigns.md)."""

from .definition import (CampaignDefinition, Task, definition_from_dict, definition_hash, load_definition, resolve,
                         tasks)
from .executor import ENGINES, run_local, run_ray, run_task
from .merge import merge_folders
from .runner import run_campaign
from .rows import EXECUTION_COLUMNS, KEY_COLUMNS, comparable, rows_frame, simulation_rows
from .store import CampaignError, assemble, prepare_folder, read_campaign, task_done, verified_table

__all__ = ["CampaignDefinition", "Task", "definition_from_dict", "definition_hash", "load_definition", "resolve",
           "tasks", "ENGINES", "run_local", "run_ray", "run_task", "merge_folders", "KEY_COLUMNS", "EXECUTION_COLUMNS",
           "comparable", "rows_frame",
           "simulation_rows", "CampaignError", "assemble", "prepare_folder", "read_campaign", "task_done",
           "verified_table", "run_campaign"]

