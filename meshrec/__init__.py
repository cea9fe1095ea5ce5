"""meshrec: recognise a touched object, and where it was touched, from three probe curves.

The method is that of "Surface Recognition by Registering Data Curves from Touch", on
meshes: the curves' local geometry (normal, Gaussian and mean curvature) is looked up in
each model's curvature table (sites spread over its smooth surface) for candidate
contacts, and a local search on surface charts finds the superposition with the least
point-to-surface error.

Typical use::

    import meshrec
    library = meshrec.ModelLibrary.from_folder("my_models/")
    touch = meshrec.TouchData.from_file("touch.csv")
    result = meshrec.recognize(touch, library)
    print(result.best.model, result.best.contact, result.best.T_model_touch)
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from meshrec._version import __version__

# The public names are imported on first use (PEP 562), so that ``import meshrec`` is
# cheap: the command line starts, and answers Ctrl-C, before numpy, scipy, trimesh and
# libigl are loaded (measured: 0.86 s to import them all eagerly, on the 2-core CI box).
_WHERE = {
    "CommonPoint": "meshrec.contact.geometry",
    "LocalGeometry": "meshrec.contact.geometry",
    "RoughFitWarning": "meshrec.contact.geometry",
    "SharpEdgeWarning": "meshrec.recognition.edges",
    "estimate_local_geometry": "meshrec.contact.geometry",
    "find_common_point": "meshrec.contact.geometry",
    "ProbeOffsetWarning": "meshrec.contact.probe",
    "RepeatedSamplesWarning": "meshrec.io.touch",
    "TouchData": "meshrec.io.touch",
    "Truth": "meshrec.io.truth",
    "read_truth": "meshrec.io.truth",
    "write_truth": "meshrec.io.truth",
    "IndexParams": "meshrec.model.index",
    "ModelIndex": "meshrec.model.index",
    "ModelLibrary": "meshrec.model.library",
    "bundled_models_dir": "meshrec.model.library",
    "load_mesh": "meshrec.model.mesh",
    "MeshWarning": "meshrec.model.mesh",
    "ResolutionWarning": "meshrec.model.resolution",
    "TouchAdvice": "meshrec.recognition.advice",
    "PoseFreedom": "meshrec.recognition.freedom",
    "pose_freedom": "meshrec.recognition.freedom",
    "next_touch": "meshrec.recognition.advice",
    "JointFit": "meshrec.recognition.joint",
    "register_touches": "meshrec.recognition.joint",
    "Recognition": "meshrec.recognition.result",
    "LibraryScreen": "meshrec.recognition.screen",
    "LibrarySites": "meshrec.recognition.screen",
    "library_sites": "meshrec.recognition.screen",
    "screen_leaders": "meshrec.recognition.screen",
    "screen_library": "meshrec.recognition.screen",
    "screen_survivors": "meshrec.recognition.screen",
    "recognize": "meshrec.recognition.recognize",
    "ProbeOffset": "meshrec.recognition.probing",
    "PhaseTimes": "meshrec.recognition.phases",
    "ModelScore": "meshrec.recognition.scoring",
    "VERDICTS": "meshrec.recognition.scoring",
    "Verdict": "meshrec.recognition.scoring",
    "WeightedPose": "meshrec.recognition.scoring",
    "PhiBrackets": "meshrec.registration.brackets",
    "phi_brackets": "meshrec.registration.brackets",
    "refine_phis": "meshrec.registration.brackets",
    "curvature_tolerance": "meshrec.registration.candidates",
    "ContactCandidates": "meshrec.registration.lookup",
    "lookup_candidates": "meshrec.registration.lookup",
    "PoseHypothesis": "meshrec.registration.poses",
    "RefinedSearch": "meshrec.registration.poses",
    "distinct_poses": "meshrec.registration.poses",
    "pose_hypotheses": "meshrec.registration.poses",
    "refine_searches": "meshrec.registration.poses",
    "Registration": "meshrec.registration.register",
    "StageTimes": "meshrec.registration.register",
    "refine_pose": "meshrec.registration.register",
    "register": "meshrec.registration.register",
    "CoarseRegistration": "meshrec.registration.register",
    "register_coarse": "meshrec.registration.register",
    "register_full": "meshrec.registration.register",
    "cascade_register": "meshrec.recognition.cascade",
    "cascade_survivors": "meshrec.recognition.cascade",
    "Screening": "meshrec.registration.screening",
    "screen_candidates": "meshrec.registration.screening",
    "Searches": "meshrec.registration.searching",
    "SearchRun": "meshrec.registration.searching",
    "search_candidates": "meshrec.registration.searching",
    "RegistrationTrace": "meshrec.registration.trace",
    "PAPER_SURFACES": "meshrec.sim.paper",
    "localisation_error": "meshrec.sim.paper",
    "symmetry_rotations": "meshrec.sim.paper",
    "SimulatedTouch": "meshrec.sim.simulate",
    "simulate_touch": "meshrec.sim.simulate",
}

if TYPE_CHECKING:  # for type checkers and editors: the same names, imported eagerly
    from meshrec.contact.geometry import (
        CommonPoint,
        LocalGeometry,
        RoughFitWarning,
        estimate_local_geometry,
        find_common_point,
    )
    from meshrec.contact.probe import ProbeOffsetWarning
    from meshrec.io.touch import RepeatedSamplesWarning, TouchData
    from meshrec.io.truth import Truth, read_truth, write_truth
    from meshrec.model.index import IndexParams, ModelIndex
    from meshrec.model.library import ModelLibrary, bundled_models_dir
    from meshrec.model.mesh import MeshWarning, load_mesh
    from meshrec.model.resolution import ResolutionWarning
    from meshrec.recognition.advice import TouchAdvice, next_touch
    from meshrec.recognition.cascade import cascade_register, cascade_survivors
    from meshrec.recognition.edges import SharpEdgeWarning
    from meshrec.recognition.freedom import PoseFreedom, pose_freedom
    from meshrec.recognition.joint import JointFit, register_touches
    from meshrec.recognition.phases import PhaseTimes
    from meshrec.recognition.probing import ProbeOffset
    from meshrec.recognition.recognize import recognize
    from meshrec.recognition.result import Recognition
    from meshrec.recognition.scoring import VERDICTS, ModelScore, Verdict, WeightedPose
    from meshrec.registration.brackets import PhiBrackets, phi_brackets, refine_phis
    from meshrec.registration.candidates import curvature_tolerance
    from meshrec.registration.lookup import ContactCandidates, lookup_candidates
    from meshrec.registration.poses import (
        PoseHypothesis,
        RefinedSearch,
        distinct_poses,
        pose_hypotheses,
        refine_searches,
    )
    from meshrec.registration.register import (
        CoarseRegistration,
        Registration,
        StageTimes,
        refine_pose,
        register,
        register_coarse,
        register_full,
    )
    from meshrec.registration.screening import Screening, screen_candidates
    from meshrec.registration.searching import Searches, SearchRun, search_candidates
    from meshrec.registration.trace import RegistrationTrace
    from meshrec.sim.paper import PAPER_SURFACES, localisation_error, symmetry_rotations
    from meshrec.sim.simulate import SimulatedTouch, simulate_touch

__all__ = [
    "PAPER_SURFACES",
    "VERDICTS",
    "CoarseRegistration",
    "CommonPoint",
    "ContactCandidates",
    "IndexParams",
    "JointFit",
    "LibraryScreen",
    "LibrarySites",
    "LocalGeometry",
    "MeshWarning",
    "ModelIndex",
    "ModelLibrary",
    "ModelScore",
    "PhaseTimes",
    "PhiBrackets",
    "PoseFreedom",
    "PoseHypothesis",
    "ProbeOffset",
    "ProbeOffsetWarning",
    "Recognition",
    "RefinedSearch",
    "Registration",
    "RegistrationTrace",
    "RepeatedSamplesWarning",
    "ResolutionWarning",
    "RoughFitWarning",
    "Screening",
    "SearchRun",
    "Searches",
    "SharpEdgeWarning",
    "SimulatedTouch",
    "StageTimes",
    "TouchAdvice",
    "TouchData",
    "Truth",
    "Verdict",
    "WeightedPose",
    "__version__",
    "bundled_models_dir",
    "cascade_register",
    "cascade_survivors",
    "curvature_tolerance",
    "distinct_poses",
    "estimate_local_geometry",
    "find_common_point",
    "library_sites",
    "load_mesh",
    "localisation_error",
    "lookup_candidates",
    "next_touch",
    "phi_brackets",
    "pose_freedom",
    "pose_hypotheses",
    "read_truth",
    "recognize",
    "refine_phis",
    "refine_pose",
    "refine_searches",
    "register",
    "register_coarse",
    "register_full",
    "register_touches",
    "screen_candidates",
    "screen_leaders",
    "screen_library",
    "screen_survivors",
    "search_candidates",
    "simulate_touch",
    "symmetry_rotations",
    "write_truth",
]


def __getattr__(name: str):
    """Import a public name on first use."""
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'meshrec' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
