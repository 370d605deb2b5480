"""Imported only by the forkserver of orthospec's pools (:func:`orthospec.workers.mp_context` preloads
it): the server is killed when the command that started it ends.

Each worker holds the server's liveness pipe, so the server would not see the command's end while a
worker runs, and the workers' own death signal (their parent is the server) would never come.
"""

from .workers import die_with_parent

die_with_parent()
