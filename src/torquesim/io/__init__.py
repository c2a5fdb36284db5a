"""Files: model TOML, result tables (CSV, OpenSim .sto), atomic writes."""

from .model_file import load_model, model_to_toml, save_model
from .tables import read_table, save_result, write_atomic

__all__ = ["load_model", "model_to_toml", "read_table", "save_model", "save_result",
           "write_atomic"]
