//! The recipe's syntax tree. Every node carries the [`Span`] it was parsed from, so every later
//! phase — checking, evaluation, planning, a controller's error — can point back at the recipe.

use crate::span::{FileId, Span};

/// A name with its span.
#[derive(Debug, Clone, PartialEq)]
pub struct Ident {
    pub name: String,
    pub span: Span,
}

/// One parsed file.
#[derive(Debug, Clone, PartialEq)]
pub struct Module {
    pub file: FileId,
    pub stmts: Vec<Stmt>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Stmt {
    pub kind: StmtKind,
    pub span: Span,
}

/// `key value` inside `laser { ... }`, `planner { ... }`, a limits group, and so on. A key with
/// no value is a flag.
#[derive(Debug, Clone, PartialEq)]
pub struct Setting {
    pub key: Ident,
    pub value: Option<Expr>,
    pub span: Span,
}

/// `x: v 200 mm/s, a 2 m/s^2` inside `limits { ... }`.
#[derive(Debug, Clone, PartialEq)]
pub struct LimitGroup {
    pub axis: Ident,
    pub settings: Vec<Setting>,
}

#[derive(Debug, Clone, PartialEq)]
pub enum MachineRef {
    /// A machine of the standard library, by name.
    Named(Ident),
    /// A machine file, by path (relative to the recipe).
    Path(StrLit),
}

#[derive(Debug, Clone, PartialEq)]
pub struct StrLit {
    pub value: String,
    pub span: Span,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Param {
    pub name: Ident,
    pub ty: Option<Ident>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct FnDef {
    pub name: Ident,
    pub params: Vec<Param>,
    pub ret: Option<Ident>,
    pub body: Vec<Stmt>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MoveKind {
    /// `move to P`: absolute, in part coordinates.
    To,
    /// `move by V`: relative to the current position.
    By,
}

#[derive(Debug, Clone, PartialEq)]
pub enum MoveSpeed {
    /// No speed given: rapid.
    Rapid,
    At(Expr),
}

#[derive(Debug, Clone, PartialEq)]
pub enum PulseStmt {
    Settings(Vec<Setting>),
    Off,
}

#[derive(Debug, Clone, PartialEq)]
pub enum LaserStmt {
    Settings(Vec<Setting>),
    On,
    Off,
}

#[derive(Debug, Clone, PartialEq)]
pub enum StmtKind {
    Machine(MachineRef),
    Limits(Vec<LimitGroup>),
    Let {
        name: Ident,
        ty: Option<Ident>,
        value: Expr,
    },
    Fn(std::rc::Rc<FnDef>),
    Import(StrLit),
    Use(StrLit),
    If {
        cond: Expr,
        then: Vec<Stmt>,
        els: Option<Vec<Stmt>>,
    },
    For {
        var: Ident,
        iter: ForIter,
        body: Vec<Stmt>,
    },
    Return(Option<Expr>),
    Laser(LaserStmt),
    Pulse(PulseStmt),
    Planner(Vec<Setting>),
    /// `rotary { diameter 60 mm }`: the object on a rotary attachment (issue 20).
    Rotary(Vec<Setting>),
    Move {
        kind: MoveKind,
        target: Expr,
        speed: MoveSpeed,
    },
    Follow {
        path: Expr,
        speed: Expr,
        settings: Vec<Setting>,
    },
    Dwell(Expr),
    MCode {
        code: Expr,
        comment: Option<StrLit>,
    },
    Event(Ident),
    /// `output NAME on|off`: a machine file's `[outputs.NAME]`.
    Output {
        name: Ident,
        on: bool,
    },
    Scan {
        kind: Ident,
        region: Expr,
        settings: Vec<Setting>,
    },
    /// A function call used as a statement.
    Expr(Expr),
}

#[derive(Debug, Clone, PartialEq)]
pub enum ForIter {
    Range {
        start: Expr,
        end: Expr,
        inclusive: bool,
    },
    Expr(Expr),
}

#[derive(Debug, PartialEq)]
pub struct Expr {
    pub kind: ExprKind,
    pub span: Span,
}

/// Cloning recurses as deep as the tree ([`crate::parser::MAX_EXPR_DEPTH`] levels at most),
/// and a debug build's clone frames are large: near the end of the stack it continues on a
/// new segment, as the checker and evaluator do.
impl Clone for Expr {
    fn clone(&self) -> Expr {
        stacker::maybe_grow(crate::STACK_RED_ZONE, crate::STACK_SEGMENT, || Expr {
            kind: self.kind.clone(),
            span: self.span,
        })
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BinOp {
    Add,
    Sub,
    Mul,
    Div,
    Rem,
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
    And,
    Or,
}

impl BinOp {
    pub fn symbol(self) -> &'static str {
        match self {
            BinOp::Add => "+",
            BinOp::Sub => "-",
            BinOp::Mul => "*",
            BinOp::Div => "/",
            BinOp::Rem => "%",
            BinOp::Eq => "==",
            BinOp::Ne => "!=",
            BinOp::Lt => "<",
            BinOp::Le => "<=",
            BinOp::Gt => ">",
            BinOp::Ge => ">=",
            BinOp::And => "and",
            BinOp::Or => "or",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnOp {
    Neg,
    Not,
}

/// A call argument, positional or named (`radius: 5 mm`).
#[derive(Debug, Clone, PartialEq)]
pub struct Arg {
    pub name: Option<Ident>,
    pub value: Expr,
}

#[derive(Debug, Clone, PartialEq)]
pub enum ExprKind {
    /// A number, with the unit literal as written (`mm/s`) and its span.
    Number {
        value: f64,
        unit: Option<(String, Span)>,
    },
    Bool(bool),
    Str(String),
    Var(String),
    /// `(x, y)` or `(x, y, z)`.
    Point(Vec<Expr>),
    List(Vec<Expr>),
    Binary {
        op: BinOp,
        lhs: Box<Expr>,
        rhs: Box<Expr>,
    },
    Unary {
        op: UnOp,
        expr: Box<Expr>,
    },
    Call {
        callee: Ident,
        args: Vec<Arg>,
    },
    Field {
        expr: Box<Expr>,
        field: Ident,
    },
    Index {
        expr: Box<Expr>,
        index: Box<Expr>,
    },
    /// `[item for var in iter if cond]`: a list built from a list or a range, filtered by an
    /// optional condition (map and filter in one form).
    Comprehension {
        item: Box<Expr>,
        var: Ident,
        iter: Box<ForIter>,
        cond: Option<Box<Expr>>,
    },
    /// `profile polyline [...] closed`: a profile constructor, its arguments and flags.
    Profile {
        kind: Ident,
        args: Vec<Arg>,
        flags: Vec<Ident>,
    },
}
