"""The names of the built-in models (`presets.PRESETS` is built in this order), readable
without loading the model code: the command line's help lists them from here."""

PREFIX = "builtin:"
PRESET_NAMES = ("elbow-curl", "knee-extension", "arm-raise", "squat-jump",
                "countermovement-jump", "squat-jump-biarticular", "drop-landing")


def preset_list() -> str:
    """``builtin:elbow-curl, builtin:knee-extension, …``: the presets as help texts list them
    (no ``|``: the CLI reference's tables would cut the help there)."""
    return ", ".join(PREFIX + name for name in PRESET_NAMES)
