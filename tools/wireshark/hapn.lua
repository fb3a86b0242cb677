-- Wireshark/tshark dissector for the haptic station wire format v3 (net/README.md).
-- Finds it on UDP by heuristic (magic "HAPN" + version 3 + header length 72) and on raw
-- Ethernet by EtherType 0x88B5 (IEEE 802 Local Experimental EtherType 1).
-- Use: tshark -X lua_script:tools/wireshark/hapn.lua -r capture.pcap -Y hapn
-- The MAC (keyed BLAKE2b-128) is shown, not verified: the session key is not in the capture.
local hapn = Proto("hapn", "Haptic station packet")

local kinds = { [1] = "state", [2] = "fingerprint" }
local HDR = 72
local f = hapn.fields
f.magic = ProtoField.uint32("hapn.magic", "Magic", base.HEX)
f.version = ProtoField.uint8("hapn.version", "Version")
f.kind = ProtoField.uint8("hapn.kind", "Payload kind", base.DEC, kinds)
f.flags = ProtoField.uint8("hapn.flags", "Flags", base.HEX)
f.float32 = ProtoField.bool("hapn.flags.float32", "float32 values", 8, nil, 0x01)
f.has_echo = ProtoField.bool("hapn.flags.has_echo", "Echo present", 8, nil, 0x02)
f.has_proxy = ProtoField.bool("hapn.flags.proxy", "Proxy position carried", 8, nil, 0x08)
f.header_len = ProtoField.uint8("hapn.header_len", "Header length")
f.session = ProtoField.uint32("hapn.session", "Session id", base.HEX)
f.sender = ProtoField.uint16("hapn.sender", "Sender station")
f.dest = ProtoField.uint16("hapn.dest", "Destination station")
f.seq = ProtoField.uint64("hapn.seq", "Sequence k")
f.send_time = ProtoField.int64("hapn.send_time_ns", "Send time (ns, sender CLOCK_MONOTONIC)")
f.echo_seq = ProtoField.uint64("hapn.echo_seq", "Echoed sequence")
f.echo_hold = ProtoField.int64("hapn.echo_hold_ns", "Echo held by the sender (ns, duration)")
f.value_count = ProtoField.uint32("hapn.value_count", "Values per vector (3n)")
f.frag_index = ProtoField.uint16("hapn.frag_index", "Fragment index")
f.frag_count = ProtoField.uint16("hapn.frag_count", "Fragment count")
f.frag_offset = ProtoField.uint32("hapn.frag_offset", "Fragment offset (bytes)")
f.frag_len = ProtoField.uint16("hapn.frag_len", "Fragment length (bytes)")
f.frag_stride = ProtoField.uint16("hapn.frag_stride", "Fragment stride (bytes)")
f.incarnation = ProtoField.uint64("hapn.incarnation", "Sender incarnation (CLOCK_REALTIME ns at its start)")
f.fp_protocol = ProtoField.uint32("hapn.fp.protocol_version", "Fingerprint: protocol version")
f.fp_nodes = ProtoField.uint32("hapn.fp.scene_nodes", "Fingerprint: scene nodes")
f.fp_scene = ProtoField.uint64("hapn.fp.scene_hash", "Fingerprint: scene hash", base.HEX)
f.fp_period = ProtoField.uint64("hapn.fp.period_ns", "Fingerprint: period (ns)")
f.fp_gains = ProtoField.uint64("hapn.fp.gains_hash", "Fingerprint: gains hash", base.HEX)
f.fp_rtt_bound = ProtoField.uint64("hapn.fp.round_trip_bound_ns", "Sender's probing round-trip bound to the destination (ns, 0 = none yet)")
f.fp_allowance = ProtoField.uint32("hapn.fp.loss_allowance_plus1", "Sender's loss allowance for the link (ticks + 1, 0 = none yet)")
f.fp_law = ProtoField.uint8("hapn.fp.consensus_law", "Fingerprint: consensus law (1 eq18, 2 pspm, 0 not sent)")
f.fp_predict = ProtoField.uint8("hapn.fp.tx_predict", "Fingerprint: predictive deadband (1 on)")
f.fp_deadband = ProtoField.uint16("hapn.fp.tx_deadband_hash", "Fingerprint: transmission deadband hash (0 off)", base.HEX)
f.fp_step_max = ProtoField.uint64("hapn.fp.step_max_ns", "Sender's step bound T^max, ns (0: not yet)")
f.payload = ProtoField.bytes("hapn.payload", "Payload slice (x_hat ++ v_hat ++ proxy)")
f.proxy = ProtoField.string("hapn.proxy", "Sender's proxy position (m)")
f.first_value = ProtoField.double("hapn.first_value", "First value in slice")
f.mac = ProtoField.bytes("hapn.mac", "MAC (keyed BLAKE2b-128)")

local e_len = ProtoExpert.new("hapn.bad_length", "Length does not match frag_len", expert.group.MALFORMED, expert.severity.ERROR)
hapn.experts = { e_len }

local MAGIC = 0x4E504148

local function looks_like(tvb)
  if tvb:len() < HDR + 16 then return false end
  return tvb(0, 4):le_uint() == MAGIC and tvb(4, 1):uint() == 3 and tvb(7, 1):uint() == HDR
end

function hapn.dissector(tvb, pinfo, tree)
  if tvb:len() < HDR + 16 then return 0 end
  pinfo.cols.protocol = "HAPN"
  local t = tree:add(hapn, tvb(), "Haptic station packet")
  t:add_le(f.magic, tvb(0, 4))
  t:add_le(f.version, tvb(4, 1))
  t:add_le(f.kind, tvb(5, 1))
  local ft = t:add_le(f.flags, tvb(6, 1))
  ft:add(f.float32, tvb(6, 1))
  ft:add(f.has_echo, tvb(6, 1))
  ft:add(f.has_proxy, tvb(6, 1))
  t:add_le(f.header_len, tvb(7, 1))
  t:add_le(f.session, tvb(8, 4))
  t:add_le(f.sender, tvb(12, 2))
  t:add_le(f.dest, tvb(14, 2))
  t:add_le(f.seq, tvb(16, 8))
  t:add_le(f.send_time, tvb(24, 8))
  t:add_le(f.echo_seq, tvb(32, 8))
  t:add_le(f.echo_hold, tvb(40, 8))
  t:add_le(f.value_count, tvb(48, 4))
  t:add_le(f.frag_index, tvb(52, 2))
  t:add_le(f.frag_count, tvb(54, 2))
  t:add_le(f.frag_offset, tvb(56, 4))
  t:add_le(f.frag_len, tvb(60, 2))
  t:add_le(f.frag_stride, tvb(62, 2))
  t:add_le(f.incarnation, tvb(64, 8))
  local flen = tvb(60, 2):le_uint()
  if HDR + flen + 16 ~= tvb:len() then
    t:add_proto_expert_info(e_len)
    return tvb:len()
  end
  local kind = tvb(5, 1):uint()
  if kind == 2 and flen == 56 then
    t:add_le(f.fp_protocol, tvb(HDR, 4))
    t:add_le(f.fp_nodes, tvb(HDR + 4, 4))
    t:add_le(f.fp_scene, tvb(HDR + 8, 8))
    t:add_le(f.fp_period, tvb(HDR + 16, 8))
    t:add_le(f.fp_gains, tvb(HDR + 24, 8))
    t:add_le(f.fp_rtt_bound, tvb(HDR + 32, 8))
    t:add_le(f.fp_allowance, tvb(HDR + 40, 4))
    t:add_le(f.fp_law, tvb(HDR + 44, 1))
    t:add_le(f.fp_predict, tvb(HDR + 45, 1))
    t:add_le(f.fp_deadband, tvb(HDR + 46, 2))
    t:add_le(f.fp_step_max, tvb(HDR + 48, 8))
  elseif flen > 0 then
    t:add(f.payload, tvb(HDR, flen))
    if bit.band(tvb(6, 1):uint(), 1) == 1 then
      t:add_le(f.first_value, tvb(HDR, 4), tvb(HDR, 4):le_float())
    elseif flen >= 8 then
      t:add_le(f.first_value, tvb(HDR, 8))
    end
    -- the proxy: the last 3 values of the last fragment, when the flag says they are meaningful
    local vb = bit.band(tvb(6, 1):uint(), 1) == 1 and 4 or 8
    if bit.band(tvb(6, 1):uint(), 8) == 8 and tvb(52, 2):le_uint() + 1 == tvb(54, 2):le_uint() and flen >= 3 * vb then
      local v = {}
      for a = 0, 2 do
        local r = tvb(HDR + flen - (3 - a) * vb, vb)
        v[a + 1] = r:le_float()  -- 4 or 8 bytes
      end
      t:add(f.proxy, tvb(HDR + flen - 3 * vb, 3 * vb), string.format("%.6f, %.6f, %.6f", v[1], v[2], v[3]))
    end
  end
  t:add(f.mac, tvb(HDR + flen, 16))
  pinfo.cols.info = string.format("%s %d -> %d seq=%s frag %d/%d", kinds[kind] or "?", tvb(12, 2):le_uint(), tvb(14, 2):le_uint(),
    tostring(tvb(16, 8):le_uint64()), tvb(52, 2):le_uint() + 1, tvb(54, 2):le_uint())
  return tvb:len()
end

local function heuristic(tvb, pinfo, tree)
  if not looks_like(tvb) then return false end
  hapn.dissector(tvb, pinfo, tree)
  return true
end

hapn:register_heuristic("udp", heuristic)
DissectorTable.get("ethertype"):add(0x88B5, hapn)
