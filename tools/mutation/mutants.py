"""The mutants run_mutants.py applies: each a weakening of Theorem 1's code that a property test
must catch. One record per mutant:

  name   short id (run_mutants.py --only NAME)
  what   the weakening, in the paper's terms
  file   path from the repository root
  old    exact text; it must occur exactly once in file (else the suite fails as stale)
  new    its replacement
  tests  "binary:Group.name" CppUTest tests, each named after a property; at least one must fail

Re-pointing a mutant after its code moved is an edit of file/old/new here. The first failing test
is enough to kill a mutant; every named one is run so the table shows which of them catch it.
"""

_RT_PASSIVE = "test_rt:Theorem1.controller_passive_eq14_at_eq18_under_adversarial_velocities_with_delays_at_the_bound"
_RT_PASSIVE_VARYING_P = "test_rt:Theorem1.under_varying_steps_the_controller_is_passive_eq14_at_eq18_with_the_P_term_at_T_max"
_RT_D_TERM = "test_rt:Theorem1.under_varying_steps_eq18s_D_term_is_needed_for_controller_passivity"
_SC_PASSIVE = "test_scenario:Theorem1Scenario.controller_passive_eq14_at_the_scenarios_eq18_under_the_worst_delays_its_network_allows"
_SC_BOUND = "test_scenario:Theorem1Scenario.no_index_delay_the_network_allows_exceeds_the_bound_eq18_was_computed_with"
_CL_BOUND = "test_sim:ClosedLoop.no_index_delay_exceeds_its_bound_in_the_paper_runs"
_CL_PASSIVE = "test_sim:ClosedLoop.n_port_passive_eq13_and_controller_passive_eq14_under_the_impaired_network"
_CL_BINDS = "test_sim:Theorem1ClosedLoop.where_eq18_binds_the_loop_is_passive_and_converges_at_eq18"
_CL_NOT_PASSIVE = "test_sim:Theorem1ClosedLoop.where_eq18_binds_a_slow_instability_at_0_85_of_it_is_reported_not_passive_never_stable"
_RULE_LATE = "test_sim:ReceiveRule.the_papers_rule_uses_late_data_so_index_delays_grow_on_the_worst_topology"
_VC_PASSIVE = "test_rt:VirtualCoupling.passive_eq25_at_the_largest_gains_eq26_accepts_under_adversarial_hand_motion"
_RT_NPMI_BALANCE = "test_rt:VariableStep.npmi_energy_balance_eq12_holds_with_a_different_step_every_tick"

# The scenario-level records target build_scenario (firmware/scenario.cpp) and the passivity budget it
# calls (firmware/model/passivity_budget.*: N-bar's allowances and eq. 18's round-trip sums).
MUTANTS = [
    dict(name="eq18_x0.5", what="eq. (18) at 0.5x", file="rt/gains.cpp",
         old="  return std::max(0.0, lambda_max(acc));\n}",
         new="  return 0.5 * std::max(0.0, lambda_max(acc));\n}",
         tests=[_RT_PASSIVE, _RT_PASSIVE_VARYING_P, _SC_PASSIVE, _CL_BINDS]),
    dict(name="eq18_x0.9", what="eq. (18) at 0.9x", file="rt/gains.cpp",
         old="  return std::max(0.0, lambda_max(acc));\n}",
         new="  return 0.9 * std::max(0.0, lambda_max(acc));\n}",
         tests=[_RT_PASSIVE, _RT_PASSIVE_VARYING_P, _SC_PASSIVE]),
    dict(name="eq18_no_D_term", what="eq. (18) without its D term", file="rt/gains.cpp",
         old="return {cP, std::max(0.0, cD)};",
         new="return {cP, 0.0 * std::max(0.0, cD)};",
         tests=[_RT_D_TERM]),
    dict(name="eq18_P_term_T_min", what="eq. (18)'s P term with T_i^min for T_j^max", file="rt/gains.cpp",
         old="const double cP = n.round_trip_ticks / 2.0 * n.t_max_j_s;",
         new="const double cP = n.round_trip_ticks / 2.0 * t_min_i;",
         tests=[_RT_PASSIVE_VARYING_P, _SC_PASSIVE]),
    dict(name="eq18_D_term_T_min", what="eq. (18)'s D term with T_i^min for T_j^max", file="rt/gains.cpp",
         old="const double cD = 0.5 * (n.t_max_j_s / t_min_i - 1.0);",
         new="const double cD = 0.5 * (t_min_i / t_min_i - 1.0);",
         tests=[_RT_D_TERM]),
    dict(name="eq26_x0.5", what="eq. (26), both bounds at 0.5x", file="rt/gains.cpp",
         old="  const double need_bd = g.B_vc_Ns_per_m * (ratio + 1.0) + g.K_vc_N_per_m * T;\n"
             "  const double need_bv = g.B_vc_Ns_per_m / 2.0 * (ratio - 1.0) + g.K_vc_N_per_m * T / 2.0;",
         new="  const double need_bd = 0.5 * (g.B_vc_Ns_per_m * (ratio + 1.0) + g.K_vc_N_per_m * T);\n"
             "  const double need_bv = 0.5 * (g.B_vc_Ns_per_m / 2.0 * (ratio - 1.0) + g.K_vc_N_per_m * T / 2.0);",
         tests=[_VC_PASSIVE]),
    dict(name="eq26_b_d_x0.5", what="eq. (26), its b_d bound at 0.5x", file="rt/gains.cpp",
         old="  const double need_bd = g.B_vc_Ns_per_m * (ratio + 1.0) + g.K_vc_N_per_m * T;",
         new="  const double need_bd = 0.5 * (g.B_vc_Ns_per_m * (ratio + 1.0) + g.K_vc_N_per_m * T);",
         tests=[_VC_PASSIVE]),
    dict(name="eq26_b_v_x0.5", what="eq. (26), its b_v bound at 0.5x", file="rt/gains.cpp",
         old="  const double need_bv = g.B_vc_Ns_per_m / 2.0 * (ratio - 1.0) + g.K_vc_N_per_m * T / 2.0;",
         new="  const double need_bv = 0.5 * (g.B_vc_Ns_per_m / 2.0 * (ratio - 1.0) + g.K_vc_N_per_m * T / 2.0);",
         tests=[_VC_PASSIVE]),
    dict(name="energy_monitor_sign", what="eq. (14) monitor: controller energy with its sign flipped", file="rt/station.cpp",
         old="  energy_.controller_J += ctrl_J;",
         new="  energy_.controller_J -= ctrl_J;",
         tests=[_RT_PASSIVE, _SC_PASSIVE, _CL_PASSIVE]),
    dict(name="port_monitor_sign", what="eq. (13) monitor: port energy with its sign flipped", file="rt/station.cpp",
         old="  energy_.port_J += contact_port_power(w_hat) * T_;",
         new="  energy_.port_J -= contact_port_power(w_hat) * T_;",
         tests=[_CL_PASSIVE, _RT_NPMI_BALANCE]),
    dict(name="rx_rule_swapped_rt", what="receive rule: newest-by-sequence keeps late packets (the paper's rule's behaviour)",
         file="rt/rx_link.cpp",
         old="    if (rule_ == RxRule::kNewestBySequence) return RxVerdict::kStale;",
         new="    if (rule_ == RxRule::kMostRecentlyReceived) return RxVerdict::kStale;",
         tests=[_CL_BOUND, _RULE_LATE]),
    # --- scenario level: firmware/scenario.cpp and firmware/model/passivity_budget.* ---
    dict(name="rx_rule_swapped_scenario", what="receive rule: the scenario hands the cores the other rule",
         file="firmware/scenario.cpp",
         old="  c.rx_rule = spec.receive_rule;",
         new="  c.rx_rule = spec.receive_rule == rt::RxRule::kNewestBySequence ? rt::RxRule::kMostRecentlyReceived : rt::RxRule::kNewestBySequence;",
         tests=[_CL_BOUND, _RULE_LATE]),
    dict(name="nbar_from_mean_delay", what="N-bar from the mean delay instead of the delay bound (guard and eq. 18)",
         file="firmware/scenario.cpp",
         old="b.nbar_ticks = model::index_delay_bounds_ticks(spec.delay_ms, spec.jitter_fraction, T,",
         new="b.nbar_ticks = model::index_delay_bounds_ticks(spec.delay_ms, 0.0, T,",
         tests=[_SC_BOUND, _SC_PASSIVE, _CL_BOUND]),
    dict(name="nbar_minus_1_eq18", what="eq. (18) with N-bar_ij - 1 and N-bar_ji - 1 (the guard keeps N-bar)",
         file="firmware/model/passivity_budget.cpp",
         old="  b.assumed_sum_ticks = b.round_trip_ticks;\n",
         new="  b.assumed_sum_ticks = b.round_trip_ticks - 2;\n",
         tests=[_SC_PASSIVE, _CL_BINDS]),
    dict(name="loss_allowance_minus_1", what="loss allowance one tick smaller (guard and eq. 18)",
         file="firmware/model/passivity_budget.hpp",
         old="int total() const { return loss_ticks + deadband_ticks + clock_ticks; }",
         new="int total() const { return loss_ticks - 1 + deadband_ticks + clock_ticks; }",
         tests=[_SC_BOUND, _SC_PASSIVE, _CL_BOUND]),
    dict(name="eq13_verdict_off", what="the verdict ignores a port energy below -d^2 (eq. 13 broken reads as stable)",
         file="firmware/model/passivity_budget.cpp",
         old="  return port_energy_min_J && *port_energy_min_J < -d2_J - 1e-9 - 1e-9 * d2_J;",
         new="  return false && port_energy_min_J && *port_energy_min_J < -d2_J - 1e-9 - 1e-9 * d2_J;",
         tests=[_CL_NOT_PASSIVE]),
]
