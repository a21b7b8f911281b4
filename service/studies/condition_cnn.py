"""The 1-D CNN baseline of the Table 9 comparison (PyTorch, CPU).

Input: the resampled raw travel window [rad], standardised with the training fold's overall
mean and spread (one scalar each: a per-sample standardisation would distort a curve differently
at each trigger delay and break the convolutions' shift invariance). Two conv–pool blocks, global average pooling, a linear head. The width and the
weight decay are chosen on a stratified 20 % validation split of the training fold (never the
test fold), then the network is retrained on the whole training fold for the chosen number of
epochs.
"""

from __future__ import annotations

import numpy as np


def torch_available() -> tuple[bool, str]:
    """Whether PyTorch imports, and why not (for skip messages)."""
    try:
        import torch  # noqa: F401
    except ImportError as exc:  # the [studies] extra is absent
        return False, f"PyTorch is not installed ({exc}); install the studies extra (torch==2.13.0)"
    return True, ""


class CNN1D:
    """Scikit-learn-like ``fit``/``predict`` around a small 1-D CNN.

    Parameters
    ----------
    seed : int
    quick : bool
        Fewer epochs and a single candidate (tests).
    """

    def __init__(self, seed: int = 0, quick: bool = False):
        self.seed, self.quick = seed, quick

    def _net(self, n_classes, width):
        import torch.nn as nn

        return nn.Sequential(
            nn.Conv1d(1, width, 7, padding=3), nn.ReLU(), nn.MaxPool1d(2),
            nn.Conv1d(width, 2 * width, 5, padding=2), nn.ReLU(), nn.MaxPool1d(2),
            nn.Conv1d(2 * width, 2 * width, 3, padding=1), nn.ReLU(),
            nn.AdaptiveAvgPool1d(1), nn.Flatten(), nn.Linear(2 * width, n_classes))

    def _train(self, X, y, width, decay, epochs, X_val=None, y_val=None):
        """Train; with a validation set, return the net and the epoch of best validation accuracy."""
        import torch

        torch.manual_seed(self.seed)
        net = self._net(self.n_classes_, width)
        opt = torch.optim.Adam(net.parameters(), lr=3e-3, weight_decay=decay)
        loss_fn = torch.nn.CrossEntropyLoss()
        Xt = torch.tensor(X[:, None, :], dtype=torch.float32)
        yt = torch.tensor(y, dtype=torch.long)
        gen = torch.Generator().manual_seed(self.seed)
        best = (-1.0, epochs)
        for epoch in range(1, epochs + 1):
            net.train()
            for idx in torch.randperm(len(yt), generator=gen).split(32):
                opt.zero_grad()
                loss_fn(net(Xt[idx]), yt[idx]).backward()
                opt.step()
            if X_val is not None and (epoch % 5 == 0 or epoch == epochs):
                acc = float(np.mean(self._predict(net, X_val) == y_val))
                if acc > best[0]:
                    best = (acc, epoch)
        return net, best

    @staticmethod
    def _predict(net, X):
        import torch

        net.eval()
        with torch.no_grad():
            return net(torch.tensor(X[:, None, :], dtype=torch.float32)).argmax(1).numpy()

    def fit(self, X, y):
        import torch
        from sklearn.model_selection import train_test_split

        torch.set_num_threads(1)  # the fits' pool owns the other core
        X, y = np.asarray(X, float), np.asarray(y)
        self.mean_, self.scale_ = X.mean(), X.std() + 1e-9
        Z = (X - self.mean_) / self.scale_
        self.n_classes_ = int(y.max()) + 1
        epochs = 40 if self.quick else 100  # selected on the validation split, every 5
        candidates = [(8, 1e-4)] if self.quick else [(8, 1e-4), (16, 1e-3)]
        tr, va = train_test_split(np.arange(len(y)), test_size=0.2, stratify=y, random_state=self.seed)
        scores = []
        for width, decay in candidates:
            _, (acc, ep) = self._train(Z[tr], y[tr], width, decay, epochs, Z[va], y[va])
            scores.append((acc, -ep, width, decay, ep))
        acc, _, width, decay, ep = max(scores)
        self.best_params_ = {"width": width, "weight_decay": decay, "epochs": ep, "val_accuracy": acc}
        self.net_, _ = self._train(Z, y, width, decay, ep)
        return self

    def predict(self, X):
        return self._predict(self.net_, (np.asarray(X, float) - self.mean_) / self.scale_)
