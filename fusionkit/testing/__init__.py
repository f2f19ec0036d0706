"""Helpers for plugin authors: numerical Jacobians and the factor contract suite.

    from fusionkit.testing import check_factor_contract
    check_factor_contract(MyFactorType)        # raises AssertionError with details on failure

or run the suite over every installed factor type with `pytest --pyargs fusionkit.testing`.
"""

from .contract import ContractFailure, FactorExample, check_factor_contract, check_factor_example
from .jacobians import numerical_jacobians

__all__ = ["ContractFailure", "FactorExample", "check_factor_contract", "check_factor_example",
           "numerical_jacobians"]
