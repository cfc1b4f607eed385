"""Prolific: its REST API (:mod:`.client`), the draft study made from ours
(:mod:`.draft`), the review of submissions by our exclusions (:mod:`.review`) and
bonuses (:mod:`.bonus`). ``manage.py prolific`` drives them."""

from .client import Client, ProlificError

__all__ = ["Client", "ProlificError"]
