"""`pin`: Pinocchio, imported when first used. Loading the plugins (every `fusionkit` command) then does
not pay its import (about 0.07 s) unless an arm is solved."""

from __future__ import annotations


class _Pinocchio:
    def __getattr__(self, name: str):
        import pinocchio
        return getattr(pinocchio, name)


pin = _Pinocchio()
