"""ISSIA-3D in the service: the sequences' import, trajectory, re-fit and export.

Importing this package registers the ISSIA kind's hooks (``app.services.kinds.issia.register_hooks``): the kind's
policy delegates its trajectory work to these modules without importing them. ``app.services`` imports this package
first, so every use of a service finds them registered.
"""
from app.services.issia.sequences import refined_with_ball, refit_after_edit
from app.services.issia.trajectory import consensus_observations, merge_doubts
from app.services.kinds.issia import IssiaHooks, register_hooks

register_hooks(IssiaHooks(consensus_observations=consensus_observations, merge_doubts=merge_doubts,
                          refined_with_ball=refined_with_ball, refit_after_edit=refit_after_edit))
