"""The Amorphous Fortress: worlds of entities each driven by a finite-state machine (Charity, Rajesh, Earle,
Togelius; QD follow-up by Earle et al.).

- :mod:`.formats`: the original's text formats (entity classes, fortress files, saved elites), read and written.

Not yet a registered domain: the engine, the QD problem and the commands come with the rest of its issue.
"""
