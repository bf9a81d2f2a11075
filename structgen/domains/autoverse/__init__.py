"""Autoverse: single-player grid games whose mechanics are rewrite rules, evolved so that a best-first search needs
many iterations to find their best play (Earle and Togelius).
"""
