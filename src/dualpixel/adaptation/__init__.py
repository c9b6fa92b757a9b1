"""A shipped model adapted to one camera from its own DP photographs, without sharp targets:
each block's blur measured from the views (:mod:`.blur_maps`), the job (:mod:`.finetune`: data,
training with the formation loss of :mod:`dualpixel.training.formation` on the crops of
:mod:`dualpixel.data.views`) and its report (:mod:`.report`)."""

from dualpixel.adaptation.finetune import AdaptSettings, adapt

__all__ = ["AdaptSettings", "adapt"]
