"""System identification: black-box subspace (MOESP, PBSID), LMS + Kung, delay estimation, metrics,
non-parametric FRFs, the nu-gap and the bootstrap; every method returns an IdentifiedModel."""

from .bootstrap import BootstrapResult, bootstrap
from .crossval import select_order
from .delay import estimate_delay, varx_input_impulse
from .freqresp import FRFEstimate, etfe, model_frf, welch_frf
from .greybox import (
                      GreyBoxModel,
                      GreyBoxResult,
                      Param,
                      oe_fit,
                      oe_fit_closed_loop,
                      periodic_average,
                      simulate_closed_loop,
                      simulate_greybox,
                      split_periods,
)
from .hinf_match import HinfMatchResult, butterworth_weight, hinf_match
from .lms import LMS, kung, lms_batch
from .logs import Log, check_identifiable, load_log, write_log
from .methods import METHODS, Method, get_method
from .metrics import simulate, vaf
from .model import IdentifiedModel
from .modelio import load_model, save_model
from .nugap import chordal_distance, nugap, stability_margin_bpc
from .structures import (
                      first_order_structure,
                      pitch_structure,
                      rate_tf_structure,
                      rigid_rig_structure,
                      tuhh_axis_structure,
)
from .subspace import moesp, pbsid

__all__ = ["BootstrapResult", "bootstrap", "select_order", "estimate_delay", "varx_input_impulse", "FRFEstimate",
           "etfe", "model_frf", "welch_frf", "GreyBoxModel", "GreyBoxResult", "Param", "oe_fit",
           "oe_fit_closed_loop", "periodic_average", "simulate_closed_loop", "simulate_greybox", "split_periods",
           "HinfMatchResult", "butterworth_weight", "hinf_match", "LMS", "kung", "lms_batch", "Log", "check_identifiable",
           "load_log", "write_log", "simulate", "vaf", "IdentifiedModel", "load_model", "save_model", "chordal_distance",
           "nugap", "stability_margin_bpc", "first_order_structure", "pitch_structure", "rate_tf_structure",
           "rigid_rig_structure", "tuhh_axis_structure", "moesp", "pbsid", "METHODS", "Method", "get_method"]
