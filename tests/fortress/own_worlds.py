"""Small worlds in the original's text formats, written for these tests, so that reading, writing, running and
replaying are tested on any clone (the originals' own files are reference data, found only on some machines)."""

from __future__ import annotations

#: A keeper that wanders until it is next to a gem, then takes one; gems wait to be taken. Placed from the map.
GEM_KEEPER = """k
-- NODES --
0: move
1: take g
-- EDGES --
0-1: nextTo g
1-0: none

g
-- NODES --
0: idle
-- EDGES --
0-0: none

-- INIT FORT --
##########
#.k......#
#........#
#....g...#
#..g.....#
#......k.#
##########
"""

#: A sprout that clones itself every third tick and a grazer that chases sprouts and takes them; placed by position.
GARDEN = """s:
-- NODES --
0: idle
1: clone
-- EDGES --
0-1: step 3
1-0: none

G:
-- NODES --
0: chase s
1: take s
-- EDGES --
0-1: touch s
1-0: none

-- INIT ENT POS --
s-[2, 2]
s-[7, 4]
G-[5, 5]
"""

#: One class in an entity file of its own, as the original's ENT/ folder keeps them: it places nothing.
LONE_CLASS = """w
-- NODES --
0: move
1: die
-- EDGES --
0-0: none
0-1: step 20
"""

#: A class whose only node is numbered 1, not 0, with an edge from 1 to 1: the original numbers nodes by their order,
#: so the node is node 0 and the edge names a node that does not exist (it can never fire).
NUMBERED_FROM_ONE = """p:
-- NODES --
1: push b
-- EDGES --
1-1: none

b:
-- NODES --
0: idle
-- EDGES --
0-0: none

-- INIT ENT POS --
p-[1, 1]
b-[2, 1]
"""
