"""The shared PPO learns: on a batched one-step task whose best action depends on the observation, the policy
comes to choose it, and its advantages cut at episode ends."""

from __future__ import annotations

import torch
from torch import nn

from structgen.ppo import PPO, EpisodeReturns, PPOSettings, Rollout


class Matching:
    """Each step shows one of four signs; the action equal to the sign pays 1, any other 0; every step ends an
    episode."""

    def __init__(self, envs: int) -> None:
        self.generator = torch.Generator().manual_seed(0)
        self.envs = envs
        self.sign = torch.randint(0, 4, (envs,), generator=self.generator)

    def observe(self) -> tuple[torch.Tensor]:
        return (nn.functional.one_hot(self.sign, 4).float(),)

    def step(self, actions: torch.Tensor):
        reward = (actions == self.sign).float()
        self.sign = torch.randint(0, 4, (self.envs,), generator=self.generator)
        return self.observe(), reward, torch.ones(self.envs, dtype=torch.bool)


class Linear(nn.Module):
    def __init__(self) -> None:
        super().__init__()
        self.actor, self.critic = nn.Linear(4, 4), nn.Linear(4, 1)

    def forward(self, sign: torch.Tensor):
        return self.actor(sign), self.critic(sign).squeeze(-1)


def test_ppo_learns_to_match_the_sign():
    torch.manual_seed(0)
    settings = PPOSettings(envs=32, steps=8, epochs=4, minibatches=4, learning_rate=0.05, entropy=0.0)
    env, ppo = Matching(settings.envs), PPO(Linear(), settings)
    returns = EpisodeReturns(settings.envs, "cpu")
    observation, means = env.observe(), []
    for _ in range(25):
        rollout = ppo.collect(env, observation)
        observation = rollout.last
        ended = returns.add_rollout(rollout)
        assert len(ended) == settings.envs * settings.steps  # every step ended an episode
        means.append(sum(ended) / len(ended))
        ppo.update(rollout)
    assert means[0] < 0.45 and means[-1] > 0.9


def test_advantages_do_not_reach_across_an_episode_end():
    ppo = PPO(Linear(), PPOSettings(envs=1, steps=3, minibatches=1, gamma=0.5, gae_lambda=1.0))
    zeros = torch.zeros(3, 1)
    rollout = Rollout(
        observations=(torch.zeros(3, 1, 4),),
        actions=zeros.long(),
        log_probs=zeros,
        values=zeros,
        rewards=torch.tensor([[0.0], [1.0], [4.0]]),
        dones=torch.tensor([[0.0], [1.0], [0.0]]),
        last=(torch.zeros(1, 4),),
        last_value=torch.tensor([8.0]),
    )
    ppo.advantages(rollout)
    # step 0 sees step 1's reward, discounted; step 1 ends its episode, so step 2's reward and the bootstrap never
    # reach it; step 2 adds the bootstrapped value
    assert torch.allclose(rollout.advantages[:, 0], torch.tensor([0.5, 1.0, 8.0]))
