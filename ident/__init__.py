"""System identification: black-box subspace (MOESP, PBSID), LMS + Kung, delay estimation, metrics,
non-parametric FRFs, the nu-gap and the bootstrap; every method returns an IdentifiedModel."""

from .model import IdentifiedModel
from .subspace import moesp, pbsid
from .lms import LMS, lms_batch, kung
from .delay import estimate_delay, varx_input_impulse
from .metrics import vaf, simulate
from .crossval import select_order
from .freqresp import FRFEstimate, welch_frf, etfe, model_frf
from .nugap import nugap, chordal_distance, stability_margin_bpc
from .bootstrap import BootstrapResult, bootstrap
from .greybox import (GreyBoxModel, GreyBoxResult, Param, oe_fit, oe_fit_closed_loop, periodic_average,
                      simulate_closed_loop, simulate_greybox)
from .structures import first_order_structure, pitch_structure, rate_tf_structure, rigid_rig_structure, tuhh_axis_structure
from .hinf_match import HinfMatchResult, butterworth_weight, hinf_match
from .logs import Log, check_identifiable, load_log, write_log
from .modelio import load_model, save_model
