"""Structured H-inf tuning of fixed-structure controllers and of the published attitude cascade."""

from .antiwindup import pid_backcalculation, riccati_antiwindup, simulate_saturated_loop
from .blocks import PID, PID2, Custom, FixedOrderSS, StaticGain, Structure
from .cascade import PlantModel, cascade_plant, generalised_plant, plant_model
from .goals import (
                    CrossoverBand,
                    Effort,
                    Margins,
                    Poles,
                    Rejection,
                    Sensitivity,
                    Tracking,
                    evaluate,
                    format_report,
                    tune_cascade,
)
from .hinfstruct import Channel, HinfstructResult, NotStabilisableError, closed_loop, hinfstruct
from .loopshaping import (
                    MixedSensitivityWeights,
                    glover_mcfarlane,
                    hinf_mixed_sensitivity,
                    modified_pid,
                    tuhh_axis_plant,
                    tuhh_generalized_plant,
                    tuhh_torque_gain,
)
from .margins import crossover_frequencies, disk_margin
from .montecarlo import MonteCarloResult, random_delta, single_loop, worst_case_delta

# robustness, margins and TUHH designs (margins() and montecarlo() stay in their modules, so that the
# submodules rotorlab.tune.margins / rotorlab.tune.montecarlo are not shadowed by same-named functions)
from .robust import HLim, additive_spread, control_sensitivity, fit_wdelta, h_lim, h_lim_analysis
from .simc import HalfRuleModel, half_rule, simc_pid
from .spec import AutopilotSpec, Spec, load_spec, parse_spec

__all__ = ["PID", "PID2", "Custom", "FixedOrderSS", "StaticGain", "Structure", "Channel", "HinfstructResult",
           "NotStabilisableError", "closed_loop", "hinfstruct", "PlantModel", "cascade_plant", "generalised_plant",
           "plant_model", "CrossoverBand", "Effort", "Margins", "Poles", "Rejection", "Sensitivity", "Tracking",
           "evaluate", "format_report", "tune_cascade", "Spec", "AutopilotSpec", "load_spec", "parse_spec", "HLim", "additive_spread",
           "control_sensitivity", "fit_wdelta", "h_lim", "h_lim_analysis", "MonteCarloResult", "random_delta",
           "single_loop", "worst_case_delta", "crossover_frequencies", "disk_margin", "MixedSensitivityWeights",
           "glover_mcfarlane", "hinf_mixed_sensitivity", "modified_pid", "tuhh_axis_plant", "tuhh_generalized_plant",
           "tuhh_torque_gain", "pid_backcalculation", "riccati_antiwindup", "simulate_saturated_loop",
           "HalfRuleModel", "half_rule", "simc_pid"]
