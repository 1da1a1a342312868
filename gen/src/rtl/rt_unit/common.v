localparam D4 = (D < 4) ? D : 4;     // entries of a spill chunk that fit a stack
localparam [1:0] ST_INACTIVE = 2'd0;  // lane_status encodings
localparam [1:0] ST_TRAVERSING = 2'd1;
localparam [1:0] ST_DONE = 2'd2;
localparam [1:0] ST_PARKED = 2'd3;
localparam [1:0] ORD_RAY = 2'd0;      // slot_order encodings
localparam [1:0] ORD_STOP = 2'd2;
localparam [1:0] ACT_NONE = 2'd0;     // a ready lane's request
localparam [1:0] ACT_FETCH = 2'd1;
localparam [1:0] ACT_SPILL = 2'd2;
localparam [1:0] ACT_FILL = 2'd3;
localparam [2:0] K_TRIANGLE = 3'd4;   // node kind of a triangle leaf
// Error kinds (bit index of the flag in `errors`).
localparam [2:0] E_ISSUE_FULL = 3'd0;
localparam [2:0] E_BAD_ISSUE = 3'd1;
localparam [2:0] E_FIFO = 3'd2;
localparam [2:0] E_UNMATCHED = 3'd3;
localparam [2:0] E_SPILL_FULL = 3'd4;
localparam [2:0] E_BAD_CHILD = 3'd5;
localparam [2:0] E_BAD_COMMAND = 3'd6;
// Request kinds.
localparam [1:0] RQ_LOAD = 2'd0;
localparam [1:0] RQ_STORE = 2'd1;
localparam [1:0] RQ_SPILL = 2'd2;
localparam [1:0] RQ_FILL = 2'd3;
// first_error fields, most significant first: valid, kind, slot, lane, ray id, value, limit.
localparam FE_W = 1 + 3 + SB + LB + RB + 128;

// ---- Helpers ------------------------------------------------------------------------------------
// Byte address of chunk `index` of stack `stack` of ray `ray`'s spill area (the area fits the
// address space, so AB bits hold every term).
function [AB-1:0] spill_address;
    input [RB-1:0] ray;
    input stack;
    input [SCW-1:0] index;
    /* verilator lint_off UNUSEDSIGNAL */
    reg [AB-1:0] a;  // the chunk's index in the area (its top 5 bits are 0)
    /* verilator lint_on UNUSEDSIGNAL */
    begin
        a = {{(AB-RB-1){1'b0}}, ray, stack} * SPC_AB + {{(AB-SCW){1'b0}}, index};
        spill_address = SBASE_AB + {a[AB-6:0], 5'd0};
    end
endfunction

// Whether a node reference cannot be held: 1..=4 chunks, 32 B aligned, inside the address space.
// Its end (address + 32 * chunks) can pass 2^AB only if every address bit from 8 up is set;
// then the chunk's index in the last 256 B plus the chunks must not pass 8 (a 3-bit add, not an
// adder and a comparator across the address).
function bad_node;
    input [63:0] address;
    input [7:0] chunks;
    reg [3:0] end_chunk;
    begin
        end_chunk = {1'b0, address[7:5]} + {1'b0, chunks[2:0]};
        bad_node = chunks == 8'd0 || chunks > 8'd4 || address[4:0] != 5'd0
            || address[63:AB] != {(64-AB){1'b0}} || (&address[AB-1:8] && end_chunk > 4'd8);
    end
endfunction

// f32 a < b (IEEE: false when either is NaN, -0 == +0).
function f32_lt;
    input [31:0] a;
    input [31:0] b;
    reg nan;
    reg zeros;
    begin
        nan = (a[30:23] == 8'hff && a[22:0] != 23'd0) || (b[30:23] == 8'hff && b[22:0] != 23'd0);
        zeros = a[30:0] == 31'd0 && b[30:0] == 31'd0;
        if (nan || zeros) f32_lt = 1'b0;
        else if (a[31] != b[31]) f32_lt = a[31];
        else if (a[31]) f32_lt = a[30:0] > b[30:0];
        else f32_lt = a[30:0] < b[30:0];
    end
endfunction

// f32 a == b (IEEE).
function f32_eq;
    input [31:0] a;
    input [31:0] b;
    reg nan;
    begin
        nan = (a[30:23] == 8'hff && a[22:0] != 23'd0) || (b[30:23] == 8'hff && b[22:0] != 23'd0);
        f32_eq = !nan && (a == b || (a[30:0] == 31'd0 && b[30:0] == 31'd0));
    end
endfunction

// Test latency of a node kind (triangle leaf: `hit` selects the hit latency).
function [DW-1:0] latency;
    input [2:0] kind;
    input hit;
    begin
        case (kind)
            3'd0: latency = LAT_HEADER;
            3'd1: latency = LAT_INTERNAL;
            3'd2: latency = LAT_INSTANCE;
            3'd3: latency = LAT_PRIMITIVE;
            3'd4: latency = hit ? LAT_TRI_HIT : LAT_TRI;
            3'd5: latency = LAT_PROCEDURAL;
            default: latency = {DW{1'b0}};
        endcase
    end
endfunction

// A lane's request this cycle: {action, stack (0 current, 1 other), spill count, node}; none
// unless the lane is ready (traversing, nothing in flight, no delay, an entry left).
function [E+5:0] lane_action;
    input [1:0] st;
    input nv;
    input [1:0] fl;
    input [DW-1:0] dl;
    input [SPW-1:0] csp;
    input [SPW-1:0] osp;
    input [SCW-1:0] csl;
    input [SCW-1:0] osl;
    input [E-1:0] ct;   // the stacks' top entries (valid when csp, osp are not 0)
    input [E-1:0] ot;
    input dual;
    reg [1:0] a;
    reg stk;
    reg [2:0] kk;
    reg [E-1:0] nd;
    reg pop_other;
    reg [15:0] after;
    begin
        a = ACT_NONE;
        stk = 1'b0;
        kk = 3'd0;
        nd = {E{1'b0}};
        pop_other = 1'b0;
        if (st == ST_TRAVERSING && !nv && fl == 2'd0 && dl == {DW{1'b0}}) begin
            if (csp != {SPW{1'b0}}) begin
                a = ACT_FETCH;
                nd = ct;
            end else if (csl != {SCW{1'b0}}) begin
                a = ACT_FILL;
            end else if (osp != {SPW{1'b0}}) begin
                a = ACT_FETCH;
                pop_other = 1'b1;
                nd = ot;
            end else if (osl != {SCW{1'b0}}) begin
                a = ACT_FILL;
                stk = 1'b1;
            end
            // After the pop, every stack that may receive children needs room for R of them.
            if (a == ACT_FETCH) begin
                after = {{(16-SPW){1'b0}}, csp} - {15'd0, !pop_other};
                if (after + R16 > D16) begin
                    a = ACT_SPILL;
                    kk = after > 16'd4 ? 3'd4 : after[2:0];
                end else if (dual) begin
                    after = {{(16-SPW){1'b0}}, osp} - {15'd0, pop_other};
                    if (after + R16 > D16) begin
                        a = ACT_SPILL;
                        stk = 1'b1;
                        kk = after > 16'd4 ? 3'd4 : after[2:0];
                    end
                end
            end
        end
        // A parked lane spills its other stack's oldest entries down to the RD a record carries.
        if (st == ST_PARKED && !nv && fl == 2'd0 && dl == {DW{1'b0}} && osp > RD_SPW) begin
            a = ACT_SPILL;
            stk = 1'b1;
            after = {{(16-SPW){1'b0}}, osp - RD_SPW};
            kk = after > 16'd4 ? 3'd4 : after[2:0];
        end
        lane_action = {a, stk, kk, nd};
    end
endfunction

// The error registers {errors, first_error} after raising error `kind` (its flag set; the first
// error captured with its slot, lane, ray id, value and limit).
function [7+FE_W-1:0] raised;
    input [6:0] flags;
    input [FE_W-1:0] first;
    input [2:0] kind;
    input [SB-1:0] slot;
    input [LB-1:0] lane;
    input [RB-1:0] ray;
    input [63:0] value;
    input [63:0] limit;
    begin
        raised = {flags | (7'd1 << kind),
                  first[FE_W-1] ? first : {1'b1, kind, slot, lane, ray, value, limit}};
    end
endfunction
