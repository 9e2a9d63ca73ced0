"""Statistical validation of materials and warps — for the built-in BSDFs and for any user's BSDF.

Every check is a function with keyword parameters that returns a result object (dataclasses with
``passed``, ``message``, the seed and the parameters), never a printout:

==========================  =================================================================================
function                    checks
==========================  =================================================================================
:func:`chi2_test`           ``sample`` against ``pdf`` (Pearson on pilot-placed, equal-probability bins)
:func:`consistency_test`    weight = eval·cos/pdf, sampled pdf = pdf(), ∫ pdf ≤ 1, reciprocity, finiteness
:func:`furnace_test`        directional albedo by quadrature and Monte Carlo agree; energy ≤ 1
:func:`delta_test`          a delta BSDF (mirror, glass): exact directions and weights, lobe frequencies vs Fresnel
:func:`stability_test`      extreme directions give no NaN, infinity, negative value or exception
:func:`run_battery`         all of them over α/θ (and a plugin's declared ``sweep``) grids
:func:`check_samples`       a file of samples from another renderer against brdflab's pdf (see
                            :mod:`brdflab.judges.samples.bsdf_checks`)
==========================  =================================================================================

Each test draws from its own random stream: the default seed is derived from the test's identity (BSDF
type, parameters, θ, which test; :func:`~brdflab.judges.core.seeding.test_seed`). A BSDF that raises, returns
wrong shapes, NaN/inf or negative values gets a failed result naming the method, the parameters and the
first offending directions (:class:`~brdflab.judges.core.guard.CheckedBSDF`).

The package is laid out by what is judged: ``material/`` (a BSDF: its sampler, pdf, energy, stability; the
battery), ``samples/`` (samples written by another renderer: BSDF and light samples), ``lights/`` (brdflab's own
light samplers), ``estimators/`` (integrators of one scene agree); ``core/`` holds the shared machinery (bins,
quadrature, seeds, the plugin guard, grouping of failures). The functions themselves are in
:mod:`brdflab.judges.public`; ``bl.validate(...)`` (the whole battery as a command) is
:func:`brdflab.workflows.validate`.
"""

from brdflab.judges.core.guard import CheckedBSDF, PluginFault
from brdflab.judges.core.seeding import test_seed
from brdflab.judges.material.battery import Battery, BSDFEntry, run_battery
from brdflab.judges.material.chi2 import SIGNIFICANCE, Chi2Result
from brdflab.judges.material.consistency import ConsistencyResult, consistency_test
from brdflab.judges.material.delta import DeltaResult, delta_test
from brdflab.judges.material.furnace import AlbedoPoint, FurnaceResult, furnace_test
from brdflab.judges.material.stability import StabilityResult, StabilityRow, stability_test
from brdflab.judges.public import (
    check_samples,
    chi2_test,
    default_seed,
    emitter_checks,
    estimator_agreement,
    warp_chi2_test,
)

__all__ = ["AlbedoPoint", "BSDFEntry", "Battery", "CheckedBSDF", "Chi2Result", "ConsistencyResult", "FurnaceResult",
           "PluginFault", "SIGNIFICANCE", "StabilityResult", "StabilityRow", "check_samples", "chi2_test",
           "consistency_test", "default_seed", "furnace_test", "run_battery", "stability_test", "test_seed",
           "warp_chi2_test", "emitter_checks", "estimator_agreement", "DeltaResult", "delta_test"]
