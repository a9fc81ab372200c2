//! pest grammar → AST with spans. Syntax errors become [`ParseError::Syntax`] with a readable
//! list of what was expected; parsing never panics.

use crate::ast::*;
use crate::diag::ParseError;
use crate::span::Span;
use pest::Parser;
use pest::iterators::Pair;
use std::rc::Rc;

#[derive(pest_derive::Parser)]
#[grammar = "grammar.pest"]
struct RecipeParser;

type P<'a> = Pair<'a, Rule>;

/// Parses one file. `base` is the file's global offset in the source map.
pub fn parse_recipe(text: &str, file: crate::FileId, base: usize) -> Result<Module, ParseError> {
    let (text, base) = skip_bom(text, base);
    check_size(text, base)?;
    check_nesting(text, base)?;
    let mut pairs = on_parse_stack(|| RecipeParser::parse(Rule::recipe, text))
        .map_err(|e| syntax_error(e, text, base))?;
    let b = Builder::new(base);
    let recipe = pairs.next().expect("recipe rule always produces one pair");
    let stmts = recipe
        .into_inner()
        .filter(|p| p.as_rule() != Rule::EOI)
        .map(|p| b.stmt(p))
        .collect();
    b.finish()?;
    Ok(Module { file, stmts })
}

/// What one line of the REPL holds: statements, or a bare expression to print.
#[derive(Debug, Clone, PartialEq)]
pub enum ReplInput {
    Stmts(Vec<Stmt>),
    Expr(Expr),
}

/// Parses REPL input: statements, or one expression whose value is to be shown.
pub fn parse_repl(text: &str, base: usize) -> Result<ReplInput, ParseError> {
    let (text, base) = skip_bom(text, base);
    check_size(text, base)?;
    check_nesting(text, base)?;
    let mut pairs = on_parse_stack(|| RecipeParser::parse(Rule::repl_input, text))
        .map_err(|e| syntax_error(e, text, base))?;
    let b = Builder::new(base);
    let input = pairs.next().expect("repl_input always produces one pair");
    let mut stmts = Vec::new();
    for p in input.into_inner() {
        match p.as_rule() {
            Rule::EOI => {}
            Rule::expr => {
                let e = b.expr(p);
                b.finish()?;
                return Ok(ReplInput::Expr(e));
            }
            _ => stmts.push(b.stmt(p)),
        }
    }
    b.finish()?;
    Ok(ReplInput::Stmts(stmts))
}

/// The text after a UTF-8 byte-order mark, and its offset. Some Windows editors start every
/// file with one; it is no part of the recipe.
fn skip_bom(text: &str, base: usize) -> (&str, usize) {
    match text.strip_prefix('\u{feff}') {
        Some(rest) => (rest, base + '\u{feff}'.len_utf8()),
        None => (text, base),
    }
}

/// True when `text` ends inside an open bracket, brace or string, so the REPL should read
/// another line before parsing.
pub fn is_incomplete(text: &str) -> bool {
    let b = brackets(text);
    b.depth > 0 || b.in_str
}

/// How deep brackets, parentheses and braces may nest. Far beyond any recipe a person writes;
/// deeper input is refused with a diagnostic before pest sees it (pest would stop with an
/// unreadable error when its stack runs low).
pub const MAX_NESTING: i32 = 128;

/// Brackets in `text` outside strings and comments.
struct Brackets {
    /// Open brackets at the end.
    depth: i32,
    in_str: bool,
    /// Byte offset of the first bracket that opens level `MAX_NESTING + 1`.
    too_deep: Option<usize>,
}

fn brackets(text: &str) -> Brackets {
    let mut b = Brackets {
        depth: 0,
        in_str: false,
        too_deep: None,
    };
    let mut chars = text.char_indices().peekable();
    while let Some((i, c)) = chars.next() {
        match c {
            '"' => b.in_str = !b.in_str,
            '/' if !b.in_str && chars.peek().map(|p| p.1) == Some('/') => {
                for (_, c) in chars.by_ref() {
                    if c == '\n' {
                        break;
                    }
                }
            }
            '(' | '[' | '{' if !b.in_str => {
                b.depth += 1;
                if b.depth > MAX_NESTING && b.too_deep.is_none() {
                    b.too_deep = Some(i);
                }
            }
            ')' | ']' | '}' if !b.in_str => b.depth -= 1,
            _ => {}
        }
    }
    b
}

/// Runs pest with room for [`MAX_NESTING`] levels whatever the thread's stack: pest recurses
/// through every precedence level per bracket (large frames in a debug build) and stops with
/// an unreadable error when its stack runs low.
fn on_parse_stack<T>(parse: impl FnOnce() -> T) -> T {
    stacker::maybe_grow(8 * 1024 * 1024, 16 * 1024 * 1024, parse)
}

/// Refuses brackets nested deeper than [`MAX_NESTING`], at the first one too deep.
fn check_nesting(text: &str, base: usize) -> Result<(), ParseError> {
    match brackets(text).too_deep {
        None => Ok(()),
        Some(at) => Err(ParseError::Syntax {
            message: format!("brackets nest more than {MAX_NESTING} deep"),
            span: Span::new(base + at, base + at + 1),
            label: format!("level {}", MAX_NESTING + 1),
            help: Some("name intermediate values with `let` instead of nesting them".into()),
        }),
    }
}

/// How deep one expression may nest: every operator, call, index, list and point between its
/// root and its deepest leaf counts one level. Brackets alone are limited by [`MAX_NESTING`],
/// but `1 mm + 1 mm + …` or `- - - x` build a tree as deep as the chain is long, and every
/// phase after the parser (checker, evaluator, and the derived `Clone`, `Drop` and `Debug` of
/// the tree) walks it recursively. A human recipe stays below a few dozen levels; the limit
/// keeps the deepest tree well inside a 512 KiB thread's stack in a debug build.
pub const MAX_EXPR_DEPTH: usize = 500;

struct Builder {
    base: usize,
    /// The first expression found nesting deeper than [`MAX_EXPR_DEPTH`]. The builder cannot
    /// fail midway (pest has already accepted the text), so it records the error, stops
    /// deepening that tree and reports it when done.
    too_deep: std::cell::RefCell<Option<ParseError>>,
}

impl Builder {
    fn new(base: usize) -> Builder {
        Builder {
            base,
            too_deep: Default::default(),
        }
    }

    fn finish(&self) -> Result<(), ParseError> {
        self.too_deep.borrow_mut().take().map_or(Ok(()), Err)
    }

    /// True when a node of `height` levels would exceed [`MAX_EXPR_DEPTH`]; records the first
    /// such node, at `at` (its operator or bracket).
    fn too_deep(&self, height: usize, at: Span) -> bool {
        if height <= MAX_EXPR_DEPTH {
            return false;
        }
        self.too_deep
            .borrow_mut()
            .get_or_insert(ParseError::TooDeep {
                limit: MAX_EXPR_DEPTH,
                span: at,
            });
        true
    }

    fn span(&self, p: &P) -> Span {
        let s = p.as_span();
        // pest's optional tails may have skipped trailing blanks and comments, which a label
        // should not underline.
        let len = trimmed_len(p.as_str());
        Span::new(self.base + s.start(), self.base + s.start() + len)
    }

    fn ident(&self, p: P) -> Ident {
        Ident {
            name: p.as_str().to_string(),
            span: self.span(&p),
        }
    }

    fn string(&self, p: P) -> StrLit {
        let span = self.span(&p);
        let value = p
            .into_inner()
            .next()
            .map(|i| i.as_str().to_string())
            .unwrap_or_default();
        StrLit { value, span }
    }

    fn block(&self, p: P) -> Vec<Stmt> {
        p.into_inner().map(|s| self.stmt(s)).collect()
    }

    fn settings(&self, p: P) -> Vec<Setting> {
        p.into_inner().map(|s| self.setting(s)).collect()
    }

    fn setting(&self, p: P) -> Setting {
        let span = self.span(&p);
        let mut it = p.into_inner();
        let key = self.ident(it.next().expect("setting has a key"));
        let value = it.next().map(|e| self.expr(e));
        Setting { key, value, span }
    }

    fn stmt(&self, p: P) -> Stmt {
        stacker::maybe_grow(crate::STACK_RED_ZONE, crate::STACK_SEGMENT, || {
            self.stmt_here(p)
        })
    }

    fn stmt_here(&self, p: P) -> Stmt {
        let span = self.span(&p);
        let rule = p.as_rule();
        let mut it = p.into_inner().filter(|p| !is_keyword(p.as_rule()));
        let mut next = || it.next().expect("grammar guarantees this child");
        let kind = match rule {
            Rule::machine_stmt => {
                let target = next();
                StmtKind::Machine(match target.as_rule() {
                    Rule::string => MachineRef::Path(self.string(target)),
                    _ => MachineRef::Named(self.ident(target)),
                })
            }
            Rule::limits_stmt => StmtKind::Limits(
                std::iter::from_fn(|| it.next())
                    .map(|g| {
                        let mut gi = g.into_inner();
                        let axis = self.ident(gi.next().expect("limit group has an axis"));
                        LimitGroup {
                            axis,
                            settings: gi.map(|s| self.setting(s)).collect(),
                        }
                    })
                    .collect(),
            ),
            Rule::let_stmt => {
                let name = self.ident(next());
                let second = next();
                let (ty, value) = if second.as_rule() == Rule::type_name {
                    (Some(self.type_name(second)), self.expr(next()))
                } else {
                    (None, self.expr(second))
                };
                StmtKind::Let { name, ty, value }
            }
            Rule::fn_stmt => {
                let name = self.ident(next());
                let mut params = Vec::new();
                let mut ret = None;
                let mut body = Vec::new();
                for c in std::iter::from_fn(|| it.next()) {
                    match c.as_rule() {
                        Rule::param => {
                            let mut pi = c.into_inner();
                            let name = self.ident(pi.next().expect("param has a name"));
                            let ty = pi.next().map(|t| self.type_name(t));
                            params.push(Param { name, ty });
                        }
                        Rule::type_name => ret = Some(self.type_name(c)),
                        Rule::block => body = self.block(c),
                        _ => {}
                    }
                }
                StmtKind::Fn(Rc::new(FnDef {
                    name,
                    params,
                    ret,
                    body,
                }))
            }
            Rule::import_stmt => StmtKind::Import(self.string(next())),
            Rule::use_stmt => {
                let t = next();
                StmtKind::Use(match t.as_rule() {
                    Rule::string => self.string(t),
                    _ => StrLit {
                        value: t.as_str().to_string(),
                        span: self.span(&t),
                    },
                })
            }
            Rule::if_stmt => {
                let cond = self.expr(next());
                let then = self.block(next());
                let els = it.next().map(|e| match e.as_rule() {
                    Rule::if_stmt => vec![self.stmt(e)],
                    _ => self.block(e),
                });
                StmtKind::If { cond, then, els }
            }
            Rule::for_stmt => {
                let var = self.ident(next());
                let iter_p = next();
                let iter = if iter_p.as_rule() == Rule::range {
                    let mut ri = iter_p.into_inner();
                    let start = self.expr(ri.next().expect("range start"));
                    let op = ri.next().expect("range op");
                    let end = self.expr(ri.next().expect("range end"));
                    ForIter::Range {
                        start,
                        end,
                        inclusive: op.as_str() == "..=",
                    }
                } else {
                    ForIter::Expr(self.expr(iter_p))
                };
                let body = self.block(next());
                StmtKind::For { var, iter, body }
            }
            Rule::return_stmt => StmtKind::Return(it.next().map(|e| self.expr(e))),
            Rule::laser_stmt => {
                let c = next();
                StmtKind::Laser(match c.as_rule() {
                    Rule::settings => LaserStmt::Settings(self.settings(c)),
                    _ if c.as_str() == "on" => LaserStmt::On,
                    _ => LaserStmt::Off,
                })
            }
            Rule::pulse_stmt => match it.next() {
                Some(c) if c.as_rule() == Rule::settings => {
                    StmtKind::Pulse(PulseStmt::Settings(self.settings(c)))
                }
                Some(c) if c.as_rule() == Rule::pulse_interval => {
                    // `pulse interval X` is shorthand for `pulse { interval X }`.
                    let cspan = self.span(&c);
                    let mut ci = c.into_inner();
                    let kw = ci.next().expect("interval keyword");
                    let key = Ident {
                        name: "interval".into(),
                        span: self.span(&kw),
                    };
                    let value = ci.next().map(|e| self.expr(e));
                    StmtKind::Pulse(PulseStmt::Settings(vec![Setting {
                        key,
                        value,
                        span: cspan,
                    }]))
                }
                _ => StmtKind::Pulse(PulseStmt::Off),
            },
            Rule::planner_stmt => StmtKind::Planner(self.settings(next())),
            Rule::rotary_stmt => StmtKind::Rotary(self.settings(next())),
            Rule::move_stmt => {
                let kind = match next().as_str() {
                    "by" => MoveKind::By,
                    _ => MoveKind::To,
                };
                let target = self.expr(next());
                let speed = match it.next() {
                    Some(e) => MoveSpeed::At(self.expr(e)),
                    None => MoveSpeed::Rapid,
                };
                StmtKind::Move {
                    kind,
                    target,
                    speed,
                }
            }
            Rule::follow_stmt => {
                let path = self.expr(next());
                let speed = self.expr(next());
                let settings = it.next().map(|s| self.settings(s)).unwrap_or_default();
                StmtKind::Follow {
                    path,
                    speed,
                    settings,
                }
            }
            Rule::dwell_stmt => StmtKind::Dwell(self.expr(next())),
            Rule::mcode_stmt => {
                let code = self.expr(next());
                let comment = it.next().map(|s| self.string(s));
                StmtKind::MCode { code, comment }
            }
            Rule::event_stmt => StmtKind::Event(self.ident(next())),
            Rule::output_stmt => {
                let name = self.ident(next());
                let on = next().as_str() == "on";
                StmtKind::Output { name, on }
            }
            Rule::scan_stmt => {
                let kind = self.ident(next());
                let region = self.expr(next());
                let settings = it.next().map(|s| self.settings(s)).unwrap_or_default();
                StmtKind::Scan {
                    kind,
                    region,
                    settings,
                }
            }
            Rule::call_stmt => StmtKind::Expr(self.expr(next())),
            other => unreachable!("not a statement rule: {other:?}"),
        };
        Stmt { kind, span }
    }

    fn type_name(&self, p: P) -> Ident {
        self.ident(p.into_inner().next().expect("type_name holds an ident"))
    }

    /// Expressions and blocks nest as deep as the source does: near the end of the stack the
    /// builder continues on a new segment instead of overflowing it (a debug build's frames
    /// are large; pest's own parse stops with an error before it runs out).
    fn expr(&self, p: P) -> Expr {
        self.expr_h(p).0
    }

    /// The expression and its height (levels from it to its deepest leaf).
    fn expr_h(&self, p: P) -> (Expr, usize) {
        stacker::maybe_grow(crate::STACK_RED_ZONE, crate::STACK_SEGMENT, || {
            self.expr_here(p)
        })
    }

    fn expr_here(&self, p: P) -> (Expr, usize) {
        let span = self.span(&p);
        let leaf = |kind| (Expr { kind, span }, 1);
        match p.as_rule() {
            Rule::expr => self.expr_h(p.into_inner().next().expect("expr has one child")),
            Rule::or_expr | Rule::and_expr | Rule::sum | Rule::product | Rule::cmp_expr => {
                let mut it = p.into_inner();
                let (mut lhs, mut h) =
                    self.expr_h(it.next().expect("binary chain has a first operand"));
                while let Some(op) = it.next() {
                    let (rhs, rh) = self.expr_h(it.next().expect("operator has a right operand"));
                    if self.too_deep(1 + h.max(rh), self.span(&op)) {
                        break;
                    }
                    h = 1 + h.max(rh);
                    let op = match op.as_str() {
                        "+" => BinOp::Add,
                        "-" => BinOp::Sub,
                        "*" => BinOp::Mul,
                        "/" => BinOp::Div,
                        "%" => BinOp::Rem,
                        "==" => BinOp::Eq,
                        "!=" => BinOp::Ne,
                        "<" => BinOp::Lt,
                        "<=" => BinOp::Le,
                        ">" => BinOp::Gt,
                        ">=" => BinOp::Ge,
                        "and" => BinOp::And,
                        _ => BinOp::Or,
                    };
                    let span = lhs.span.to(rhs.span);
                    lhs = Expr {
                        kind: ExprKind::Binary {
                            op,
                            lhs: Box::new(lhs),
                            rhs: Box::new(rhs),
                        },
                        span,
                    };
                }
                (lhs, h)
            }
            Rule::unary => {
                let children: Vec<P> = p.into_inner().collect();
                let (ops, operand) = children.split_at(children.len() - 1);
                let (mut e, mut h) = self.expr_h(operand[0].clone());
                for op in ops.iter().rev() {
                    if self.too_deep(h + 1, self.span(op)) {
                        break;
                    }
                    h += 1;
                    let op = if op.as_str() == "-" {
                        UnOp::Neg
                    } else {
                        UnOp::Not
                    };
                    e = Expr {
                        kind: ExprKind::Unary {
                            op,
                            expr: Box::new(e),
                        },
                        span,
                    };
                }
                (e, h)
            }
            Rule::postfix => {
                let mut it = p.into_inner();
                let (mut e, mut h) = self.expr_h(it.next().expect("postfix has a primary"));
                for suffix in it {
                    let s_span = e.span.to(self.span(&suffix));
                    let inner = suffix.clone().into_inner().next().expect("suffix body");
                    let (index, ih) = match suffix.as_rule() {
                        Rule::field => (None, 0),
                        _ => {
                            let (i, ih) = self.expr_h(inner.clone());
                            (Some(i), ih)
                        }
                    };
                    if self.too_deep(1 + h.max(ih), self.span(&suffix)) {
                        break;
                    }
                    h = 1 + h.max(ih);
                    let expr = Box::new(e);
                    let kind = match index {
                        None => ExprKind::Field {
                            expr,
                            field: self.ident(inner),
                        },
                        Some(i) => ExprKind::Index {
                            expr,
                            index: Box::new(i),
                        },
                    };
                    e = Expr { kind, span: s_span };
                }
                (e, h)
            }
            Rule::quantity => {
                let mut it = p.into_inner();
                let n = it.next().expect("quantity has a number");
                let u = it.next().expect("quantity has a unit");
                leaf(ExprKind::Number {
                    value: parse_number(n.as_str()),
                    unit: Some((u.as_str().to_string(), self.span(&u))),
                })
            }
            Rule::number => leaf(ExprKind::Number {
                value: parse_number(p.as_str()),
                unit: None,
            }),
            Rule::kw_true => leaf(ExprKind::Bool(true)),
            Rule::kw_false => leaf(ExprKind::Bool(false)),
            Rule::string => leaf(ExprKind::Str(self.string(p).value)),
            Rule::ident => leaf(ExprKind::Var(p.as_str().to_string())),
            Rule::paren => {
                let (mut items, h) = self.exprs_h(p.into_inner());
                if items.len() == 1 {
                    // Parentheses only group; keep the outer span for diagnostics.
                    let mut e = items.remove(0);
                    e.span = span;
                    (e, h)
                } else {
                    self.node(ExprKind::Point(items), span, h + 1)
                }
            }
            Rule::list => {
                let inner: Vec<P> = p.into_inner().collect();
                if let [first, tail] = &inner[..]
                    && tail.as_rule() == Rule::comp_tail
                {
                    let (item, mut h) = self.expr_h(first.clone());
                    let mut it = tail.clone().into_inner().filter(|c| {
                        !matches!(c.as_rule(), Rule::kw_for | Rule::kw_in | Rule::kw_if)
                    });
                    let var = self.ident(it.next().expect("comprehension variable"));
                    let iter_p = it.next().expect("comprehension source");
                    let iter = if iter_p.as_rule() == Rule::range {
                        let mut ri = iter_p.into_inner();
                        let (start, sh) = self.expr_h(ri.next().expect("range start"));
                        let op = ri.next().expect("range op");
                        let (end, eh) = self.expr_h(ri.next().expect("range end"));
                        h = h.max(sh).max(eh);
                        ForIter::Range {
                            start,
                            end,
                            inclusive: op.as_str() == "..=",
                        }
                    } else {
                        let (e, eh) = self.expr_h(iter_p);
                        h = h.max(eh);
                        ForIter::Expr(e)
                    };
                    let cond = it.next().map(|c| {
                        let (e, ch) = self.expr_h(c);
                        h = h.max(ch);
                        Box::new(e)
                    });
                    return self.node(
                        ExprKind::Comprehension {
                            item: Box::new(item),
                            var,
                            iter: Box::new(iter),
                            cond,
                        },
                        span,
                        h + 1,
                    );
                }
                let (items, h) = self.exprs_h(inner.into_iter());
                self.node(ExprKind::List(items), span, h + 1)
            }
            Rule::call => {
                let mut it = p.into_inner();
                let callee = it.next().expect("call has a callee");
                let callee = Ident {
                    name: callee.as_str().to_string(),
                    span: self.span(&callee),
                };
                let (args, h) = self.args(it.next().expect("call has arguments"));
                self.node(ExprKind::Call { callee, args }, span, h + 1)
            }
            Rule::profile_expr => {
                let mut it = p.into_inner().filter(|c| c.as_rule() != Rule::kw_profile);
                let kind = self.ident(it.next().expect("profile has a kind"));
                let mut args = Vec::new();
                let mut flags = Vec::new();
                let mut h = 0;
                for c in it {
                    match c.as_rule() {
                        Rule::call_args => (args, h) = self.args(c),
                        Rule::profile_flag => flags.push(self.ident(c)),
                        _ => {
                            let (value, vh) = self.expr_h(c);
                            h = vh;
                            args.push(Arg { name: None, value });
                        }
                    }
                }
                self.node(ExprKind::Profile { kind, args, flags }, span, h + 1)
            }
            other => unreachable!("not an expression rule: {other:?}"),
        }
    }

    /// A node holding other expressions, `height` levels high; a placeholder when that is too
    /// deep (the error is recorded, and the tree must not grow past the limit meanwhile).
    fn node(&self, kind: ExprKind, span: Span, height: usize) -> (Expr, usize) {
        if self.too_deep(height, span) {
            return (
                Expr {
                    kind: ExprKind::Bool(false),
                    span,
                },
                1,
            );
        }
        (Expr { kind, span }, height)
    }

    /// The expressions and the greatest of their heights.
    fn exprs_h<'a>(&self, items: impl Iterator<Item = P<'a>>) -> (Vec<Expr>, usize) {
        let mut h = 0;
        let v = items
            .map(|p| {
                let (e, eh) = self.expr_h(p);
                h = h.max(eh);
                e
            })
            .collect();
        (v, h)
    }

    /// The arguments and the greatest of their heights.
    fn args(&self, p: P) -> (Vec<Arg>, usize) {
        let mut h = 0;
        let args = p
            .into_inner()
            .map(|a| {
                let mut it = a.into_inner();
                let first = it.next().expect("arg has content");
                let (name, value) = match it.next() {
                    Some(value) => (Some(self.ident(first)), value),
                    None => (None, first),
                };
                let (value, vh) = self.expr_h(value);
                h = h.max(vh);
                Arg { name, value }
            })
            .collect();
        (args, h)
    }
}

/// The largest recipe, import or REPL input lase parses: 4 MiB. A hand-written recipe is a few
/// kB; the parser holds about 3 kB per point of a literal point list (pest's token queue and
/// the AST), so a 27 MB file of a million points took 50 s and 2.9 GB. Refused before parsing.
pub const MAX_SOURCE_BYTES: usize = 4 * 1024 * 1024;

fn check_size(text: &str, base: usize) -> Result<(), ParseError> {
    if text.len() <= MAX_SOURCE_BYTES {
        return Ok(());
    }
    let at = (0..=MAX_SOURCE_BYTES)
        .rev()
        .find(|&i| text.is_char_boundary(i))
        .unwrap_or(0);
    let end = (at + 1..=text.len())
        .find(|&i| text.is_char_boundary(i))
        .unwrap_or(text.len());
    Err(ParseError::TooLarge {
        size_mib: text.len() as f64 / (1024.0 * 1024.0),
        limit_mib: MAX_SOURCE_BYTES / (1024 * 1024),
        span: Span::new(base + at, base + end),
    })
}

/// The length of `text` without trailing white space and comments.
fn trimmed_len(text: &str) -> usize {
    let mut t = text;
    loop {
        let before = t.len();
        t = t.trim_end();
        if t.ends_with("*/")
            && let Some(open) = t.rfind("/*")
        {
            t = &t[..open];
        }
        let line_start = t.rfind('\n').map_or(0, |i| i + 1);
        let mut in_str = false;
        let bytes = t.as_bytes();
        let mut i = line_start;
        while i < bytes.len() {
            match bytes[i] {
                b'"' => in_str = !in_str,
                b'/' if !in_str && bytes.get(i + 1) == Some(&b'/') => {
                    t = &t[..i];
                    break;
                }
                _ => {}
            }
            i += 1;
        }
        if t.len() == before {
            return t.len();
        }
    }
}

fn parse_number(s: &str) -> f64 {
    // The grammar admits only valid float syntax; an absurd exponent parses to infinity, which
    // the checker reports.
    s.parse().unwrap_or(f64::NAN)
}

fn is_keyword(r: Rule) -> bool {
    matches!(
        r,
        Rule::kw_machine
            | Rule::kw_limits
            | Rule::kw_let
            | Rule::kw_fn
            | Rule::kw_import
            | Rule::kw_use
            | Rule::kw_if
            | Rule::kw_else
            | Rule::kw_for
            | Rule::kw_in
            | Rule::kw_return
            | Rule::kw_laser
            | Rule::kw_pulse
            | Rule::kw_planner
            | Rule::kw_rotary
            | Rule::kw_move
            | Rule::kw_rapid
            | Rule::kw_at
            | Rule::kw_follow
            | Rule::kw_dwell
            | Rule::kw_mcode
            | Rule::kw_event
            | Rule::kw_output
            | Rule::kw_scan
            | Rule::kw_interval
    )
}

/// The words a user reads in "expected ..." lists.
fn rule_name(r: Rule) -> Option<&'static str> {
    Some(match r {
        Rule::EOI => "end of input",
        Rule::expr
        | Rule::or_expr
        | Rule::and_expr
        | Rule::cmp_expr
        | Rule::sum
        | Rule::product
        | Rule::unary
        | Rule::postfix => "an expression",
        Rule::ident | Rule::callee | Rule::arg_name => "a name",
        Rule::number | Rule::quantity => "a number",
        Rule::unit | Rule::unit_atom => "a unit",
        Rule::string => "a string",
        Rule::settings => "`{ key value, ... }`",
        Rule::setting => "a setting (`key value`)",
        Rule::limit_group => "an axis group (`x: v 200 mm/s, a 2 m/s^2`)",
        Rule::block => "a block `{ ... }`",
        Rule::call_args => "arguments `( ... )`",
        Rule::arg => "an argument",
        Rule::list => "a list `[ ... ]`",
        Rule::comp_tail => "`for` (a list comprehension)",
        Rule::paren => "`(`",
        Rule::cmp_op => "a comparison",
        Rule::add_op | Rule::mul_op => "an operator",
        Rule::range | Rule::range_op => "a range `a..b`",
        Rule::type_name => "a type name",
        Rule::param => "a parameter",
        Rule::field => "`.field`",
        Rule::index => "`[index]`",
        Rule::move_kind => "`to` or `by`",
        Rule::laser_onoff => "`on` or `off`",
        Rule::pulse_interval => "`interval`",
        Rule::profile_flag => "`closed`, `cw` or `ccw`",
        Rule::profile_expr => "`profile`",
        Rule::kw_machine
        | Rule::kw_limits
        | Rule::kw_let
        | Rule::kw_fn
        | Rule::kw_import
        | Rule::kw_use
        | Rule::kw_if
        | Rule::kw_for
        | Rule::kw_return
        | Rule::kw_laser
        | Rule::kw_pulse
        | Rule::kw_planner
        | Rule::kw_rotary
        | Rule::kw_move
        | Rule::kw_follow
        | Rule::kw_dwell
        | Rule::kw_mcode
        | Rule::kw_event
        | Rule::kw_output
        | Rule::kw_scan
        | Rule::call_stmt
        | Rule::machine_stmt
        | Rule::limits_stmt
        | Rule::let_stmt
        | Rule::fn_stmt
        | Rule::import_stmt
        | Rule::use_stmt
        | Rule::if_stmt
        | Rule::for_stmt
        | Rule::return_stmt
        | Rule::laser_stmt
        | Rule::pulse_stmt
        | Rule::planner_stmt
        | Rule::rotary_stmt
        | Rule::move_stmt
        | Rule::follow_stmt
        | Rule::dwell_stmt
        | Rule::mcode_stmt
        | Rule::event_stmt
        | Rule::output_stmt
        | Rule::scan_stmt => "a statement",
        Rule::kw_else => "`else`",
        Rule::kw_in => "`in`",
        Rule::kw_to => "`to`",
        Rule::kw_by => "`by`",
        Rule::kw_at => "`at`",
        Rule::kw_rapid => "`rapid`",
        Rule::kw_true | Rule::kw_false => "`true` or `false`",
        Rule::kw_interval => "`interval`",
        Rule::kw_on | Rule::kw_off => "`on` or `off`",
        Rule::kw_not => "`not`",
        Rule::kw_and | Rule::kw_or => "`and` or `or`",
        Rule::kw_profile => "`profile`",
        Rule::kw_closed | Rule::kw_cw | Rule::kw_ccw => "`closed`, `cw` or `ccw`",
        _ => return None,
    })
}

fn syntax_error(e: pest::error::Error<Rule>, text: &str, base: usize) -> ParseError {
    use pest::error::{ErrorVariant, InputLocation};
    let (start, end) = match e.location {
        InputLocation::Pos(p) => (p, p),
        InputLocation::Span((s, e)) => (s, e),
    };
    // Point at the offending token, not at an empty position, when there is one.
    let tok_end = if end > start {
        end
    } else {
        text[start..]
            .char_indices()
            .find(|(_, c)| c.is_whitespace() || "()[]{},;:".contains(*c))
            .map(|(i, _)| start + i.max(text[start..].chars().next().map_or(0, char::len_utf8)))
            .unwrap_or(text.len())
    };
    let found = text[start..tok_end].trim();
    let found = if found.is_empty() {
        if start >= text.len() {
            "end of input".to_string()
        } else {
            "a line break".to_string()
        }
    } else {
        format!("`{found}`")
    };
    let mut expected: Vec<&str> = match &e.variant {
        ErrorVariant::ParsingError { positives, .. } => {
            positives.iter().filter_map(|r| rule_name(*r)).collect()
        }
        ErrorVariant::CustomError { .. } => Vec::new(),
    };
    expected.sort();
    expected.dedup();
    let list = match expected.len() {
        0 => "something else".to_string(),
        1 => expected[0].to_string(),
        n => format!("{} or {}", expected[..n - 1].join(", "), expected[n - 1]),
    };
    let word = text[start..tok_end].trim();
    let is_word = !word.is_empty()
        && word.chars().all(|c| c.is_alphanumeric() || c == '_')
        && !word.starts_with(|c: char| c.is_ascii_digit());
    let keyword = is_word && crate::schema::KEYWORDS.contains(&word);
    // A keyword where a name is due (`let at = ...`) is a name the language keeps.
    let found = if keyword && expected.contains(&"a name") {
        format!("the keyword {found}")
    } else {
        found
    };
    let help = if keyword && expected.contains(&"a name") {
        Some(format!(
            "`{word}` is a keyword of the language and cannot name a value; choose another \
             name, e.g. `{word}_1`"
        ))
    } else if let Some(kw) = is_word
        .then(|| misspelt_statement(word, &expected))
        .flatten()
    {
        // The long list of what could follow an expression statement hides the real slip.
        return ParseError::Syntax {
            message: format!("`{word}` starts no statement; did you mean `{kw}`?"),
            span: Span::new(base + start, base + tok_end),
            label: format!("did you mean `{kw}`?"),
            help: Some(format!(
                "`{kw}` is the statement keyword closest to `{word}`; `lase doc statements` \
                 lists them all"
            )),
        };
    } else if found == "`=`" && expected.contains(&"a comparison") {
        Some("`=` only binds names in `let`; compare with `==`".to_string())
    } else if expected.contains(&"a unit") || found.starts_with("`mm") {
        Some("a unit follows its number on the same line: `20 mm/s`".to_string())
    } else {
        None
    };
    ParseError::Syntax {
        message: format!("expected {list}, found {found}"),
        span: Span::new(base + start, base + tok_end),
        label: format!("expected {list}"),
        help,
    }
}

/// The statement keyword a word where a statement may start is a misspelling of
/// (`folow` → `follow`), by the same similarity as names' suggestions.
fn misspelt_statement(word: &str, expected: &[&str]) -> Option<&'static str> {
    if !expected.contains(&"a statement") || crate::schema::KEYWORDS.contains(&word) {
        return None;
    }
    const STATEMENT_KEYWORDS: &[&str] = &[
        "machine", "limits", "let", "fn", "import", "use", "if", "for", "return", "laser", "pulse",
        "planner", "rotary", "move", "follow", "dwell", "mcode", "event", "scan",
    ];
    crate::units::suggest(word, STATEMENT_KEYWORDS.iter().copied())
}

#[cfg(test)]
mod tests;
