"""A plain, slow fortress simulation written from the research notes (gridworlds.md, B2), for the tests to hold the
compiled engine to. Entities are objects in an insertion-ordered dict, as in the original; randomness is numpy's
``rng.choice`` over the original's direction lists, so nothing here shares the engine's random-number shortcut.
"""

from __future__ import annotations

import numpy as np

WIDTH, HEIGHT, CAP = 15, 8, 156
DIRECTIONS = [[0, 1], [0, -1], [1, 0], [-1, 0]]


class Ent:
    def __init__(self, ident, char, x, y):
        self.id, self.char, self.pos = ident, char, [x, y]
        self.node, self.age, self.moved = 0, 0, None


class ReferenceFortress:
    def __init__(self, world, seed):
        # world: FortressFile; classes keep their file order
        self.world = world
        self.nodes = {c: e.nodes for c, e in world.classes.items()}
        self.edges = {c: list(e.edges.items()) for c, e in world.classes.items()}
        self.rng = np.random.default_rng(seed)
        self.entities: dict[int, Ent] = {}
        self.next_id = 0
        self.visits = {c: {"nodes": set(), "edges": set()} for c in world.classes}
        for c, x, y in world.initial:
            if self.first_at(x, y) is None:
                self.add(c, x, y)
        self.ticks = 0

    def add(self, c, x, y):
        self.entities[self.next_id] = Ent(self.next_id, c, x, y)
        self.next_id += 1

    def valid(self, x, y):
        return 0 < x < WIDTH - 1 and 0 < y < HEIGHT - 1

    def first_at(self, x, y):
        for e in self.entities.values():
            if e.pos == [x, y]:
                return e
        return None

    def closest(self, me, c):
        found = [e for e in self.entities.values() if e.char == c and e.id != me.id]
        if not found:
            return None
        return sorted(found, key=lambda e: abs(e.pos[0] - me.pos[0]) + abs(e.pos[1] - me.pos[1]))[0]

    def near(self, me, c, r):
        return any(
            e.id != me.id and e.char == c and abs(e.pos[0] - me.pos[0]) <= r and abs(e.pos[1] - me.pos[1]) <= r
            for e in self.entities.values()
        )

    def act(self, me, action):
        name, _, c = action.partition(" ")
        if name in ("move", "move_wall", "clone", "add"):
            d = self.rng.choice(DIRECTIONS)
            x, y = me.pos[0] + int(d[0]), me.pos[1] + int(d[1])
            if not self.valid(x, y):
                return
            if name == "move":
                me.pos = [x, y]
            elif name == "move_wall":
                there = self.first_at(x, y)
                if there is None or there.char != c:
                    me.pos = [x, y]
            elif self.first_at(x, y) is None:
                self.add(me.char if name == "clone" else c, x, y)
        elif name == "die":
            self.entities.pop(me.id, None)
        elif name == "take":
            other = self.closest(me, c)
            if other is not None:
                self.entities.pop(other.id)
        elif name == "chase":
            other = self.closest(me, c)
            if other is None:
                return
            wanted = []
            if other.pos[0] > me.pos[0]:
                wanted.append("east")
            elif other.pos[0] < me.pos[0]:
                wanted.append("west")
            if other.pos[1] > me.pos[1]:
                wanted.append("south")
            elif other.pos[1] < me.pos[1]:
                wanted.append("north")
            if not wanted:
                return
            step = {"east": (1, 0), "west": (-1, 0), "south": (0, 1), "north": (0, -1)}[self.rng.choice(wanted)]
            x, y = me.pos[0] + step[0], me.pos[1] + step[1]
            if self.valid(x, y):
                me.pos = [x, y]
        elif name == "push":
            other = self.closest(me, c)
            if other is None:
                return
            d = self.rng.choice(DIRECTIONS)
            x, y = me.pos[0] + int(d[0]), me.pos[1] + int(d[1])
            if [x, y] == other.pos:
                bx, by = x + int(d[0]), y + int(d[1])
                if self.valid(bx, by):
                    me.pos, other.pos = [x, y], [bx, by]
            elif self.valid(x, y):
                me.pos = [x, y]
        elif name == "transform":
            self.add(c, me.pos[0], me.pos[1])
            self.entities.pop(me.id, None)

    def condition(self, me, text):
        name, *args = text.split(" ")
        if name == "none":
            return True
        if name == "step":
            return me.age % int(args[0]) == 0
        if name == "touch":
            return self.near(me, args[0], 0)
        if name == "nextTo":
            return self.near(me, args[0], 1)
        return self.near(me, args[0], int(args[1]))

    def update(self, me):
        me.age += 1
        self.act(me, self.nodes[me.char][me.node])
        priority = {"touch": 4, "nextTo": 3, "within": 2, "step": 1, "none": 0}
        out = [(k, v) for k, v in self.edges[me.char] if k.split("-")[0] == str(me.node)]
        out.sort(key=lambda kv: -priority[kv[1].split(" ")[0]])  # stable: file order within a priority
        me.moved = None
        for key, text in out:
            if self.condition(me, text):
                me.node, me.moved = int(key.split("-")[1]), key
                break
        self.visits[me.char]["nodes"].add(me.node)
        if me.moved is not None:
            self.visits[me.char]["edges"].add(me.moved)

    def run(self, steps):
        """Ticks until a stop; returns the entities after each tick, t = 0 first."""
        states = [self.snapshot()]
        while self.entities and len(self.entities) <= CAP and self.ticks < steps:
            self.ticks += 1
            for ident in list(self.entities):
                if ident in self.entities:
                    self.update(self.entities[ident])
            states.append(self.snapshot())
        return states

    def snapshot(self):
        return [(e.char, e.pos[0], e.pos[1], e.node) for e in self.entities.values()]

    def fitness(self):
        visited = sum(len(v["nodes"]) + len(v["edges"]) for v in self.visits.values())
        size = sum(len(self.nodes[c]) + len(self.edges[c]) for c in self.nodes)
        return visited / size
