"""Mazes: start and goal, scripted and learned agents that walk them, and the paper's maze experiment."""
