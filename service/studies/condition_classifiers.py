"""Condition classifiers for the Table 9 comparison: the proposed nearest-nominal rule on the
estimated parameters, and the SVM and BPNN baselines on raw travel samples (scikit-learn).

Every classifier follows scikit-learn's ``fit(X, y)`` / ``predict(X)`` so one cross-validation
loop runs them all on the same folds. Baselines tune their hyperparameters with an inner
stratified CV on the training fold only.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import median_abs_deviation


class NearestNominal:
    """Assign a sample to the condition with the nearest nominal parameter vector.

    The nominal vector of a condition is the mean of its training estimates. Distances are
    Euclidean after dividing each parameter by a training spread, so parameters of different
    units and magnitudes weigh alike (paper Section 4.5).

    Parameters
    ----------
    normalise : {"within", "global"}
        ``within``: the pooled within-condition standard deviation of the training fold (the
        spread of one condition's estimates, default); ``global``: each parameter's standard
        deviation over the whole training fold.

    setting_columns : sequence of int, optional
        Design-nominal vectors: only these columns (the parameters the design says the setting
        moves, e.g. BO for the opening spring's nut) get a nominal per condition; every other
        column's nominal is its median over all training conditions. A unit's offset in those
        other parameters (manufacturing tolerance) then adds the same amount to every distance
        and cannot move the decision. None: every column per condition (issue 5's rule).

    A sample whose fit failed (NaN) is assigned the label -1 (never correct).
    """

    def __init__(self, normalise: str = "within", setting_columns=None):
        if normalise not in ("within", "global"):
            raise ValueError(f"normalise must be 'within' or 'global', got {normalise!r}")
        self.normalise = normalise
        self.setting_columns = None if setting_columns is None else tuple(setting_columns)

    def fit(self, X, y):
        X, y = np.asarray(X, float), np.asarray(y)
        ok = np.all(np.isfinite(X), axis=1)
        X, y = X[ok], y[ok]
        self.classes_ = np.unique(y)
        self.nominal_ = np.array([np.median(X[y == c], axis=0) for c in self.classes_])
        if self.setting_columns is not None:
            common = np.ones(X.shape[1], dtype=bool)
            common[list(self.setting_columns)] = False
            self.nominal_[:, common] = np.median(X[:, common], axis=0)
        if self.normalise == "global":
            scale = X.std(axis=0, ddof=1)
        else:
            resid = X - self.nominal_[np.searchsorted(self.classes_, y)]
            # Robust spread (MAD): one outlying fit must not flatten a parameter's weight.
            scale = median_abs_deviation(resid, axis=0, scale="normal")
        self.scale_ = np.where(scale > 0, scale, 1.0)
        return self

    def predict(self, X):
        X = np.asarray(X, float)
        d = np.linalg.norm((X[:, None, :] - self.nominal_[None]) / self.scale_, axis=2)
        labels = self.classes_[np.argmin(np.where(np.isfinite(d), d, np.inf), axis=1)]
        return np.where(np.all(np.isfinite(X), axis=1), labels, -1)


def _inner_cv(y, seed):
    from sklearn.model_selection import StratifiedKFold

    n_min = int(np.min(np.bincount(np.asarray(y))[np.unique(y)]))
    return StratifiedKFold(n_splits=max(2, min(3, n_min)), shuffle=True, random_state=seed)


def make_svm(seed: int = 0, quick: bool = False):
    """RBF SVM on standardised travel samples; C and γ tuned by inner CV on the training fold."""
    from sklearn.model_selection import GridSearchCV
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC

    grid = {"svc__C": [1, 100] if quick else [0.1, 1, 10, 100, 1000],
            "svc__gamma": ["scale"] if quick else ["scale", 1e-4, 1e-3, 1e-2]}
    return _Tuned(lambda y: GridSearchCV(make_pipeline(StandardScaler(), SVC(kernel="rbf")), grid,
                                         cv=_inner_cv(y, seed), n_jobs=1), )


def make_bpnn(seed: int = 0, quick: bool = False):
    """Back-propagation network (scikit-learn MLP, L-BFGS); hidden width and L2
    penalty tuned by inner CV on the training fold."""
    from sklearn.model_selection import GridSearchCV
    from sklearn.neural_network import MLPClassifier
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    grid = {"mlpclassifier__hidden_layer_sizes": [(32,)] if quick else [(32,), (128,)],
            "mlpclassifier__alpha": [1e-2] if quick else [1e-3, 1e-1, 10.0]}
    # L-BFGS: full-batch and fast on a few hundred samples (Adam needed ~70 s per fold here).
    mlp = MLPClassifier(solver="lbfgs", max_iter=100 if quick else 300, random_state=seed)
    return _Tuned(lambda y: GridSearchCV(make_pipeline(StandardScaler(), mlp), grid,
                                         cv=_inner_cv(y, seed), n_jobs=1))


class _Tuned:
    """A GridSearchCV built per training fold (its inner CV depends on the fold's class counts)."""

    def __init__(self, build):
        self.build = build

    def fit(self, X, y):
        import warnings

        from sklearn.exceptions import ConvergenceWarning

        self.search_ = self.build(y)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            self.search_.fit(X, y)
        self.best_params_ = self.search_.best_params_
        return self

    def predict(self, X):
        return self.search_.predict(X)


def cross_validate(make, X, y, folds) -> dict:
    """Accuracy per fold and the pooled confusion matrix of one method on fixed ``folds``.

    Parameters
    ----------
    make : callable
        ``make() -> classifier`` (a fresh one per fold).
    X : ndarray (n, f)
    y : ndarray (n,)
        Condition labels 0..K-1.
    folds : list of (train_idx, test_idx)

    Returns
    -------
    dict
        ``fold_accuracy`` (list), ``mean``, ``sd`` (fractions), ``confusion`` (K × K, rows true),
        ``best_params`` (per fold, when tuned).
    """
    from threadpoolctl import threadpool_limits

    k = int(np.max(y)) + 1
    conf = np.zeros((k, k), dtype=int)
    acc, best = [], []
    for train, test in folds:
        # One BLAS thread: on a shared 2-core machine more threads spin and run ~20× slower.
        with threadpool_limits(1):
            clf = make().fit(X[train], y[train])
            pred = np.asarray(clf.predict(X[test]))
        acc.append(float(np.mean(pred == y[test])))
        for t, p in zip(y[test], pred):
            if p >= 0:
                conf[t, p] += 1
        best.append({str(a): _plain(b) for a, b in getattr(clf, "best_params_", {}).items()})
    return {"fold_accuracy": acc, "mean": float(np.mean(acc)), "sd": float(np.std(acc, ddof=1)) if len(acc) > 1 else 0.0,
            "confusion": conf.tolist(), "best_params": best}


def _plain(v):
    if isinstance(v, tuple):
        return list(v)
    if isinstance(v, np.generic):
        return v.item()
    return v


def train_test(make, X_train, y_train, X_test, y_test) -> dict:
    """Train one classifier on one set and score it on another (the cross-unit protocol).

    Returns
    -------
    dict
        ``accuracy`` (fraction), ``confusion`` (K × K, rows true; a rejected sample, label -1,
        counts in no column), ``best_params`` (when tuned).
    """
    from threadpoolctl import threadpool_limits

    k = int(max(np.max(y_train), np.max(y_test))) + 1
    with threadpool_limits(1):
        clf = make().fit(X_train, y_train)
        pred = np.asarray(clf.predict(X_test))
    conf = np.zeros((k, k), dtype=int)
    for t, p in zip(y_test, pred):
        if p >= 0:
            conf[t, p] += 1
    return {"accuracy": float(np.mean(pred == y_test)), "confusion": conf.tolist(),
            "best_params": {str(a): _plain(b) for a, b in getattr(clf, "best_params_", {}).items()}}
