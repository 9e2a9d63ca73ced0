"""Statistics users can trust: image checks (``brdflab check``) and intervals over independent runs."""

from brdflab.stats.intervals import holm, log_ratio_interval, sidak, t_interval, welch_df
from brdflab.stats.jobs import RenderJob, make_integrator, run_job, run_progressive, run_seed
from brdflab.stats.render_check import CheckResult, Estimate, check_images, run_check

__all__ = ["CheckResult", "Estimate", "RenderJob", "check_images", "holm", "log_ratio_interval",
           "make_integrator", "run_check", "run_job", "run_progressive", "run_seed", "sidak", "t_interval",
           "welch_df"]
