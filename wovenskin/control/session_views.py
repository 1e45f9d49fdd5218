"""What views ask a control session besides its state: which limits hold the arm back."""

from __future__ import annotations

import numpy as np


class SessionViews:
    """The view questions of :class:`~wovenskin.control.session.ControlSession`."""

    def holding(self) -> tuple[str, ...]:
        """Which limits hold the arm back now, one line each, for the views: the safety
        layer's report (a latched stop with how it ends, the speed cap, a workspace box
        face, a joint margin) and a simulated arm's own slow-down near a singularity or a
        joint's speed limit while a twist runs.  Empty when nothing holds it."""
        held = list(getattr(self.safety, "limiting", ()))
        if self.safety.stopped:
            if self._user_stop:
                return ("STOP pressed: Resume (or space) to move again",)
            if self.state.gesture is not None:
                held.append("lift your fingers: it resumes once the skin streams again")
            elif self._held is not None:
                held.append("release the key or button: it resumes once the skin streams again")
            else:
                held.append("resumes by itself once the skin streams again")
            return tuple(held)
        if not self.state.action.startswith("twist"):
            return ()
        info = getattr(self.robot, "ik_info", None)
        scale = float(getattr(info, "scale", 1.0))
        why = getattr(info, "limited_by", None)
        if why and scale < 0.999 and np.any(self.state.twist):
            held.append(f"{why}: the arm moves at {scale:.0%} of the command")
        return tuple(held)
